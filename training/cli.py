"""`python -m training {train,teacher,distill,export-phase,export-checkpoint,kneel-report,evaluate}`: the command
line of the training side.

Heavy imports (jax, brax, the MJX envs) happen inside the subcommands, so `--help` is instant.
"""
from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path
from typing import Sequence

from common.events import LYING_SIDES
from messages import contract

# = training.envs.TASKS (checked when the envs load)
TASKS = ("joystick", "getup", "getup_kneel", "getup_roll", "getup_stand", "getup_baseline", "unified")
RUNS_DIR = "runs"   # experiments' default home (ignored by git): = training.recipes.campaign.RUNS_ROOT


# ---------------------------------------------------------------- subcommands
def _cmd_train(args, command: str) -> int:
    from training.ppo import train  # lazy: keeps JAX out of --help
    out = args.out or f"{RUNS_DIR}/{args.name or args.task}"
    result = train.train(
        args.task, out, steps=args.steps, num_envs=args.envs, seed=args.seed, resume=args.resume,
        max_minutes=args.max_minutes, overrides=args.config, from_checkpoint=args.from_,
        preset="toy" if args.toy else args.preset, ship=args.ship, name=args.name, command=command,
        progress=not args.no_progress, backend=args.backend)
    state = "complete" if result.complete else "stopped at a checkpoint (--max-minutes): run again with --resume"
    print(f"{result.run_dir}: {result.env_steps:,}/{result.target_steps:,} env steps, {state}; "
          f"{result.env_steps_per_s:,.0f} env-steps/s; artifact {result.artifact}")
    return 0


def _cmd_teacher(args, command: str) -> int:
    from training.distill import teacher  # lazy: keeps JAX out of --help
    report = teacher.check_teacher(args.getup, args.joystick, num_envs=args.envs, seed=args.seed,
                                   steps=args.check_steps)
    print(report)
    return 0


def _cmd_distill(args, command: str) -> int:
    from training.distill import dagger as distill  # lazy: keeps JAX out of --help
    from training.distill import teacher as T  # lazy: keeps JAX out of --help
    if not (args.chain or args.getup or args.joystick) or (args.chain and args.getup):
        raise ValueError("distill: give either --getup and --joystick (the stitched teacher), --chain ROLL,RISE,STAND "
                         "(the keyframe chain), or --chain and --joystick (the chain below the waist switch)")
    if args.chain:
        parts = [p.strip() for p in args.chain.split(",")]
        if len(parts) != len(T.CHAIN) or not all(parts):
            raise ValueError(f"distill: --chain takes {len(T.CHAIN)} artifacts, ROLL,RISE,STAND; got {args.chain!r}")
        teacher = {**dict(zip(T.CHAIN, parts)), **({"joystick": args.joystick} if args.joystick else {})}
    elif not (args.getup and args.joystick):
        raise ValueError("distill: the stitched teacher needs both --getup and --joystick")
    else:
        teacher = {"getup": args.getup, "joystick": args.joystick}
    result = distill.distill(
        teacher, args.out or f"{RUNS_DIR}/{args.name}", task=args.task, overrides=args.config,
        preset="toy" if args.toy else "gpu", seed=args.seed, num_envs=args.envs, ship=args.ship,
        command=command, progress=not args.no_progress, max_minutes=args.max_minutes, backend=args.backend,
        name=args.name, from_checkpoint=args.from_, end_at=args.end_at)
    print(f"{result.run_dir}: {result.dagger_steps} DAgger phases, artifact {result.artifact} "
          f"(output rule {result.output_rule})")
    return 0


def _cmd_export_phase(args, command: str) -> int:
    from training.distill import dagger as distill  # lazy: keeps JAX out of --help
    path = distill.export_phase(args.run, args.phase, args.name, args.like)
    print(f"{path}: DAgger phase {args.phase} of {args.run}")
    return 0


def _cmd_export_checkpoint(args, command: str) -> int:
    from training.ppo import train  # lazy: keeps JAX out of --help
    path = train.export_checkpoint(args.run, args.steps, args.name, like=args.like)
    what = "the checkpoint" if len(args.steps) == 1 else "the mean of the checkpoints"
    print(f"{path}: {what} at {', '.join(map(str, args.steps))} env steps of {args.run}")
    return 0


def _cmd_kneel_report(args, command: str) -> int:
    from training.ppo import kneel_report  # lazy: keeps JAX out of --help
    rows = kneel_report.report(args.run, seeds=args.seeds, seconds=args.seconds, steps=args.steps, like=args.like,
                               mean=args.mean)
    print(f"{args.run}/{kneel_report.REPORT}: {len(rows)} rows")
    return 0


def _cmd_recipe(args, command: str) -> int:
    from training.recipes import runner as recipe_runner  # lazy: keeps JAX out of --help
    if args.list:
        print(recipe_runner.describe())
        return 0
    if not args.name:
        raise ValueError("name a recipe, or --list")
    root = Path(args.out) if args.out else recipe_runner.RUNS_ROOT
    if args.save_campaign:
        for path in recipe_runner.save_campaign(args.name, root):
            print(f"saved {path}")
        return 0
    if args.toy and args.ship:
        raise ValueError("--toy runs train nothing to ship")
    recipe_runner.run(args.name, stage=args.stage, root=root, resume=args.resume, max_minutes=args.max_minutes,
                      backend=args.backend, toy=args.toy, ship=args.ship, progress=not args.no_progress)
    return 0


BACKEND_CHOICES = ("mjx", "cpu")   # = training.envs.base.BACKENDS (not imported: parsing needs no JAX)
BACKEND_HELP = "physics engine (default: mjx when JAX sees a GPU, else cpu = MuJoCo C on all cores)"
EVAL_SECONDS = {"getup": 10.0, "joystick": 20.0}   # default episode length per evaluated task [s]
# = training.evaluation.batch.START_KINDS and JOYSTICK_STARTS (not imported: parsing needs no JAX)
START_CHOICES = ("fallen", "knockdown", "wall", "push")
JOYSTICK_STARTS = ("knockdown", "wall", "push")
# evaluate --starts knockdown|wall|push: the shipped joystick expert
START_JOYSTICK = "policies/joystick/joystick.safetensors"


def _cmd_evaluate(args, command: str) -> int:
    seconds = EVAL_SECONDS[args.task] if args.seconds is None else args.seconds
    out = args.out or f"out/eval_{args.task}"
    if args.start_joystick and args.starts not in JOYSTICK_STARTS:
        raise ValueError("--start-joystick goes with --starts knockdown, wall or push")
    if args.starts in JOYSTICK_STARTS and not args.start_joystick:
        args.start_joystick = START_JOYSTICK
    if args.task == "joystick":
        if args.baseline:
            raise ValueError("--baseline: the joystick evaluation takes one policy")
        if args.starts != "fallen":
            raise ValueError("--starts: the joystick evaluation starts standing")
        if args.target_noise or args.handover_up_error is not None:
            raise ValueError("--target-noise, --handover-up-error: the getup evaluation only")
        from training.evaluation import joystick as evaluate_joystick  # lazy: keeps JAX out of --help
        report = evaluate_joystick.evaluate(args.policy, out, episodes=args.seeds, seconds=seconds,
                                            first_seed=args.first_seed, command=command, backend=args.backend)
    else:
        from training.evaluation import batch as evaluate  # lazy: keeps JAX out of --help
        report = evaluate.evaluate(args.policy, out, baseline=args.baseline, task=args.task,
                                   seeds=args.seeds, seconds=seconds, first_seed=args.first_seed,
                                   command=command, backend=args.backend, starts=args.starts,
                                   start_joystick=args.start_joystick, target_noise_rad=args.target_noise,
                                   handover_up_error=args.handover_up_error)
    print(report.read_text())
    return 0


def _common(p, seed=True):
    if seed:
        p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-progress", action="store_true", help="no tqdm bar (logs, CI)")


def _add_train(sub) -> None:
    p = sub.add_parser("train", help="PPO run (brax ppo.train), resumable, time-boxed")
    p.add_argument("task", choices=TASKS)
    p.add_argument("--out", help="run directory (checkpoints, curves, artifact); default runs/<name>")
    p.add_argument("--steps", type=int, help="target env steps in total (default: the task config's)")
    p.add_argument("--envs", type=int, help="parallel envs (default: the preset's, 8192 on GPU)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    p.add_argument("--max-minutes", type=float, help="stop at the last checkpoint that fits in this wall time")
    p.add_argument("--from", dest="from_", metavar="CHECKPOINT",
                   help="initialise from a checkpoint folder or run directory (fine-tunes; steps restart at 0)")
    p.add_argument("--config", action="append", default=[], metavar="KEY=VALUE",
                   help="override a PPO (ppo.*) or env (env.*) config field; repeatable")
    p.add_argument("--toy", action="store_true", help="tiny CPU preset; the artifact is marked untrained")
    p.add_argument("--preset", choices=("gpu", "cpu"), default="gpu",
                   help="PPO sizes: gpu (8192 envs, Playground's recipe) or cpu (256 envs, see ppo/train.py)")
    p.add_argument("--backend", choices=BACKEND_CHOICES, help=BACKEND_HELP)
    p.add_argument("--name", help="policy name (default: the task)")
    p.add_argument("--ship", action="store_true",
                   help="when complete: copy the artifact to policies/<name>/ and append a row to its CARD.md")
    _common(p)
    p.set_defaults(func=_cmd_train)


def _add_teacher(sub) -> None:
    p = sub.add_parser("teacher", help="build the stitched teacher and roll it out briefly as a check")
    p.add_argument("--getup", required=True, help="getup expert: artifact (.safetensors) or checkpoint/run dir")
    p.add_argument("--joystick", required=True, help="joystick expert: artifact or checkpoint/run dir")
    p.add_argument("--envs", type=int, default=16)
    p.add_argument("--check-steps", type=int, default=50, help="control steps of the check rollout")
    _common(p)
    p.set_defaults(func=_cmd_teacher)


def _add_distill(sub) -> None:
    p = sub.add_parser("distill", help="DAgger (brax bc) student from the stitched teacher or the keyframe chain")
    p.add_argument("--getup", help="the stitched teacher's getup expert (with --joystick)")
    p.add_argument("--joystick", help="the stitched teacher's joystick expert (with --getup, or with --chain: above "
                                      "the waist switch)")
    p.add_argument("--chain", metavar="ROLL,RISE,STAND",
                   help="the keyframe getup's latched chain as the teacher (alone: the student is a getup policy, "
                        "--task getup; with --joystick: the chain below the waist switch, the joystick expert above)")
    p.add_argument("--out", help="run directory; default runs/<name>")
    p.add_argument("--task", choices=TASKS, default="unified",
                   help="env the student is rolled out in (default unified: fallen/kneeling/standing starts, "
                        "joystick commands, pushes, falls)")
    p.add_argument("--envs", type=int)
    p.add_argument("--max-minutes", type=float)
    p.add_argument("--config", action="append", default=[], metavar="KEY=VALUE",
                   help="override a DAgger (bc.*) or env (env.*) config field; repeatable")
    p.add_argument("--toy", action="store_true")
    p.add_argument("--ship", action="store_true")
    p.add_argument("--name", default="student",
                   help="policy name: the artifact's file name and manifest name (default: student)")
    p.add_argument("--from", dest="from_", metavar="CHECKPOINT",
                   help="go on from a distill run's checkpoint (or its run directory → the newest) into a new --out; "
                        "the phase count, curve and provenance continue")
    p.add_argument("--end-at", type=int, metavar="PHASE",
                   help="end the run, finished, at this phase's checkpoint (its schedule stays that of "
                        "bc.dagger_steps)")
    p.add_argument("--backend", choices=BACKEND_CHOICES, help=BACKEND_HELP)
    _common(p)
    p.set_defaults(func=_cmd_distill)


def _add_export_phase(sub) -> None:
    p = sub.add_parser("export-phase", help="export a finished distill run's checkpoint at an earlier DAgger "
                       "phase (e.g. the seed's DAgger-400 / DAgger-1000 of Fig. 5.1)")
    p.add_argument("--run", required=True, help="distill run directory")
    p.add_argument("--phase", type=int, required=True, help="DAgger phase of a checkpoint in RUN/checkpoints")
    p.add_argument("--name", required=True, help="policy name: RUN/NAME.safetensors")
    p.add_argument("--like", help="the run's final artifact, whose manifest is reused (default: the one "
                   "RUN/distill_state.json names)")
    p.set_defaults(func=_cmd_export_phase)


def _add_export_checkpoint(sub) -> None:
    p = sub.add_parser("export-checkpoint", help="export a PPO run's kept checkpoint at an earlier epoch "
                       "(the run keeps its last few)")
    p.add_argument("--run", required=True, help="train run directory")
    p.add_argument("--steps", type=int, nargs="+", required=True,
                   help="env steps of a checkpoint in RUN/checkpoints (several: the mean of their policies)")
    p.add_argument("--name", required=True, help="policy name: RUN/NAME.safetensors")
    p.add_argument("--like", help="an artifact of the same env and network whose manifest fields are reused "
                   "(default: the run's own export, or mid-run its --from run's)")
    p.set_defaults(func=_cmd_export_checkpoint)
    p = sub.add_parser("kneel-report", help="stage 1's batch figures of each kept checkpoint of a run not yet in "
                       "its report (RUN/report.md, report.json)")
    p.add_argument("--run", required=True, help="train run directory (a getup_kneel run)")
    p.add_argument("--steps", type=int, nargs="+", help="only these checkpoints (env steps; default: every kept one)")
    p.add_argument("--mean", action="store_true", help="also the mean of those checkpoints' policies (one row)")
    p.add_argument("--seeds", type=int, default=200, help="fallen seeds 0 … SEEDS − 1")
    p.add_argument("--seconds", type=float, default=8.0, help="episode length [s] (§4.8's gate within 8 s)")
    p.add_argument("--like", help="an artifact of the same env and network whose manifest fields the exports reuse "
                   "(default: as export-checkpoint's)")
    p.set_defaults(func=_cmd_kneel_report)


def _add_evaluate(sub) -> None:
    p = sub.add_parser("evaluate", help="batched rollouts of an artifact: getup from seeded fallen "
                       "starts, or joystick command tracking")
    p.add_argument("--policy", required=True, help="policy artifact (.safetensors); for getup also GETUP,UPRIGHT: "
                   f"the runtime's composite of two (getup below waist {contract.WAIST_SWITCH_HEIGHT_M:g} m, upright "
                   "above)")
    p.add_argument("--baseline", help="second policy to compare against (getup): an artifact or GETUP,UPRIGHT")
    p.add_argument("--task", choices=tuple(EVAL_SECONDS), default="getup")
    p.add_argument("--seeds", type=int, default=32,
                   help="episodes: seeded fallen starts (getup) or seeded joystick episodes")
    p.add_argument("--first-seed", type=int, default=0)
    p.add_argument("--starts", choices=START_CHOICES, default="fallen",
                   help="getup: fallen = settled after the runtime's PREPARE (the loop's getup test); knockdown = "
                   "mid-fall, where the stitched teacher hands over after a push (as the loop's push test): "
                   "--start-joystick is pushed over from SEEDS standing starts, the ones it caught are left out; "
                   "wall = the same after --start-joystick walked into the low-wall course from SEEDS approaches "
                   "(training/envs/wall_course.py), those that stepped over it left out; push = the same in the "
                   "loop's push test: SEEDS standing starts shoved on the torso forward or backward (2 : 1), "
                   "the ones it caught left out")
    p.add_argument("--start-joystick", "--knockdown-joystick", metavar="ARTIFACT", dest="start_joystick",
                   help="with --starts knockdown, wall or push: the joystick expert that walks and is pushed over or "
                   f"trips (default {START_JOYSTICK})")
    p.add_argument("--seconds", type=float, help="episode length [s] (default: getup 10, joystick 20)")
    p.add_argument("--target-noise", type=float, default=0.0, metavar="RAD",
                   help="getup, CPU backend: N(0, RAD²) on every joint target each tick (seeded by --first-seed), "
                   "as PPO's sampled actions: does the behaviour survive the training rollouts' noise")
    p.add_argument("--handover-up-error", type=float, metavar="E",
                   help="a chain:ROLL,RISE,STAND policy's rise hands over to the stand at ‖u − e_z‖ < E "
                        "(default: §4.8's gate, 0.01)")
    p.add_argument("--out", help="folder for the report (default: out/eval_<task>)")
    p.add_argument("--backend", choices=BACKEND_CHOICES, help=BACKEND_HELP)
    p.set_defaults(func=_cmd_evaluate)


def _cmd_strip(args, command: str) -> int:
    from training.evaluation import strip  # lazy: keeps JAX out of --help
    path, seed, labels = strip.getup_strip(args.policy, args.out, lying=args.lying, first_seed=args.first_seed,
                                           seconds=args.seconds, frames=args.frames,
                                           handover_up_error=args.handover_up_error)
    print(f"{path}: fallen seed {seed} ({args.lying.replace('_', ' ')}), frames at {', '.join(labels)}")
    return 0


def _add_strip(sub) -> None:
    p = sub.add_parser("strip", help="a frame strip of one getup from a held-back fallen start (a card's figure)")
    p.add_argument("--policy", required=True, help="getup artifact, GETUP,UPRIGHT, or a keyframe chain (its folder "
                   "or chain:ROLL,RISE,STAND)")
    p.add_argument("--lying", choices=LYING_SIDES, default="on_back",
                   help="the first fallen seed lying this way is drawn")
    p.add_argument("--first-seed", type=int, default=9500, help="where the search for that seed starts (default: "
                   "the held-back seeds' first)")
    p.add_argument("--seconds", type=float, default=15.0, help="episode length [s]")
    p.add_argument("--frames", type=int, default=8)
    p.add_argument("--handover-up-error", type=float, metavar="E", help="a chain's rise → stand hand-over, "
                   "‖u − e_z‖ < E (default: its folder's, or §4.8's gate)")
    p.add_argument("--out", required=True, help="the strip's PNG")
    p.set_defaults(func=_cmd_strip)


def _add_recipe(sub) -> None:
    p = sub.add_parser("recipe", help="run a named recipe (training/recipes/): a shipped policy's chain of stages")
    p.add_argument("name", nargs="?", help="recipe name (see --list)")
    p.add_argument("--list", action="store_true", help="list the recipes, their policies and stages")
    p.add_argument("--stage", help="run only this stage (the stages it starts from must be complete)")
    p.add_argument("--resume", action="store_true", help="go on with an unfinished stage (from runs/, else from "
                   "the campaign in training/campaigns/<name>/)")
    p.add_argument("--max-minutes", type=float, help="stop at the last checkpoint that fits in this wall time")
    p.add_argument("--backend", choices=BACKEND_CHOICES, help=BACKEND_HELP)
    p.add_argument("--out", help="runs root (default runs/): stage S of recipe N runs in OUT/N/S")
    p.add_argument("--toy", action="store_true", help="every stage at toy size (smoke test; nothing is trained)")
    p.add_argument("--ship", action="store_true", help="when the last stage is complete: copy the artifact to "
                   "policies/<policy>/ and append a row to its CARD.md")
    p.add_argument("--save-campaign", action="store_true", help="copy each stage's newest checkpoint, run state "
                   "and curve into training/campaigns/<name>/ (no training)")
    p.add_argument("--no-progress", action="store_true", help="no tqdm bar (logs, CI)")
    p.set_defaults(func=_cmd_recipe)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m training", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    for add in (_add_train, _add_teacher, _add_distill, _add_export_phase, _add_export_checkpoint, _add_evaluate,
                _add_strip, _add_recipe):
        add(sub)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    command = "python -m training " + " ".join(shlex.quote(a) for a in argv)
    try:
        return args.func(args, command)
    except (ValueError, FileNotFoundError, FileExistsError) as e:
        print(f"python -m training {args.command}: error: {e}", file=sys.stderr)
        return 2
