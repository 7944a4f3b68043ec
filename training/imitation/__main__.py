"""`python -m training.imitation`: DAgger with the rise planner as the expert, into one campaign folder.

    python -m training.imitation --out DIR [--demos DIR] [--rounds R] [--config key=value ...] [--max-minutes M]
                                 [--policy ARTIFACT] [--lying face_down|on_back|side | --rolled-by ROLL]

`--config` sets training/imitation/config.py's fields (e.g. starts_per_round=8) or, prefixed `planner.`, the
planner's (training/planner/config.py). A folder with finished rounds resumes at its next round (its config must
match). The batch evaluations of each round go to --eval-dir (default runs/imitation_eval)."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from training.imitation import dagger
from training.imitation.campaign import run


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m training.imitation", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, type=Path, help="the campaign folder")
    p.add_argument("--demos", type=Path, default=dagger.DEFAULT_DEMOS, help="the planner's demonstrations (round 0)")
    p.add_argument("--rounds", type=int, default=None, help="stop after this many rounds (default: config.rounds)")
    p.add_argument("--config", action="append", default=[], metavar="KEY=VALUE", help="a setting, repeatable")
    p.add_argument("--max-minutes", type=float, default=None, help="start no new round after this long")
    p.add_argument("--refit", action="store_true",
                   help="redo the rounds' fits and evaluations with the current fit settings on the stored data")
    p.add_argument("--policy", type=Path, default=None,
                   help="an artifact of the learner's network (e.g. a PPO fine-tune's checkpoint) that the next "
                        "round rolls out and refits from, in place of the campaign's learner")
    p.add_argument("--lying", default="", help="the next round starts only from fallen starts lying this way "
                                                "(face_down, on_back, side): labels where that side's rises fail")
    p.add_argument("--rolled-by", type=Path, default=None,
                   help="a roll policy (getup_roll artifact): the next round starts where it hands the on-back and "
                        "side falls over to the rise")
    p.add_argument("--eval-dir", type=Path, default=None, help="where each round's batch evaluation goes")
    args = p.parse_args(argv)
    try:
        if args.rounds is not None and args.rounds < 1:
            raise ValueError(f"--rounds must be at least 1, got {args.rounds}")
        state = run(args.out, args.config, args.demos, args.rounds, args.max_minutes, args.eval_dir, args.refit,
                    args.policy, args.lying, args.rolled_by)
    except ValueError as e:
        print(f"imitation: {e}", file=sys.stderr)
        return 2
    print(json.dumps(state["rounds"][-1] if state["rounds"] else {}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
