"""`python -m training.planner`: plan rises to the kneel from the loop's fallen starts and store them.

    python -m training.planner --seeds 0:100 --out DIR [--config samples=96 ...] [--max-minutes M] [--jobs N]

Each seed's start is the getup env's fallen start of that seed after the runtime's PREPARE ramp; its plan
is seeded by the seed, so a folder is reproducible from its config. A seed whose demo_<seed>.npz is already in
DIR is kept (a stopped run goes on). DIR gets report.json after every demo and, at the end, frame strips of a
face-down and an on-the-back rise (strip_face_down.png, strip_on_back.png). --jobs N plans N seeds at once in
worker processes (each seed's plan depends only on its seed, so the folder is the same)."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from training.planner.batch import run


def parse_seeds(text: str) -> list[int]:
    """'A:B' (A … B − 1) or 'A,B,C'."""
    try:
        if ":" in text:
            a, b = (int(x) for x in text.split(":"))
            seeds = list(range(a, b))
        else:
            seeds = [int(x) for x in text.split(",")]
    except ValueError:
        raise ValueError(f"--seeds {text!r}: expected A:B or A,B,C (non-negative integers)") from None
    if not seeds or min(seeds) < 0:
        raise ValueError(f"--seeds {text!r}: expected at least one non-negative seed")
    return seeds


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m training.planner", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", required=True, help="fallen-start seeds: A:B or A,B,C")
    p.add_argument("--out", required=True, type=Path, help="the demonstrations' folder")
    p.add_argument("--config", action="append", default=[], metavar="KEY=VALUE",
                   help="planner setting (training/planner/config.py), repeatable")
    p.add_argument("--max-minutes", type=float, default=None, help="start no new seed after this long")
    p.add_argument("--jobs", type=int, default=1, help="seeds planned at once, one worker process each")
    args = p.parse_args(argv)
    try:
        seeds = parse_seeds(args.seeds)
        report = run(seeds, args.out, args.config, args.max_minutes, jobs=args.jobs)
    except ValueError as e:
        print(f"planner: {e}", file=sys.stderr)
        return 2
    print(json.dumps(report.get("summary", {}), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
