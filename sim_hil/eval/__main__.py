"""`python -m sim_hil.eval <scenario> --policy STUDENT [--baseline GETUP,JOYSTICK] [--teacher GETUP,JOYSTICK] ...`

Seeded lockstep trials of the student (one artifact) and, with --baseline / --teacher, a composite (getup
policy below waist 0.5 m, joystick policy above: t1-runtime --policy-upright): the baseline composite of
chapter 6, or the stitched teacher the student was distilled from (fig5.1: the seed's Fig. 5.1). Writes
report.md, plots.png, video.mp4 and results.json under --out (default out/eval/<scenario>). Run inside
tools/netns (make eval-*). Two trials run at once at most (--jobs), each sim+runtime pair on its own LCM port.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import shlex
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from pathlib import Path

from common import keyframe_chain
from sim_hil.eval.plans import PLANS
from sim_hil.eval.trial import Controller, init_worker, run_job, trial_log_name

ROOT = Path(__file__).resolve().parents[2]
MAX_JOBS = 2            # the machine has 2 cores: at most 2 sim+runtime pairs
EXIT_OK, EXIT_USAGE, EXIT_FAILED = 0, 2, 1
DEFAULT_LABEL = "student"


def distilled_from(student: Path) -> str:
    """GETUP,JOYSTICK: the stitched teacher a distilled artifact names in its provenance (paths as given to
    `python -m training distill`, relative to the repository root)."""
    from common.artifact import artifact_problem, read_artifact, stitched_teacher
    problem = artifact_problem(student)
    if problem:
        raise ValueError(f"policy artifact {problem}")
    teacher = stitched_teacher(read_artifact(student)[3])
    if teacher is None:
        raise ValueError(f"{student}: its provenance names no teacher (not a distilled student); give --teacher")
    return ",".join(str(p if Path(p).is_absolute() else ROOT / p) for p in (teacher["getup"], teacher["joystick"]))


def _refuse(problem: str):
    """A bad artifact: one line naming it (not argparse's usage block) and the usage exit code."""
    print(f"sim_hil.eval: {problem}", file=sys.stderr)
    raise SystemExit(EXIT_USAGE)


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="python -m sim_hil.eval", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenario", choices=sorted(PLANS))
    ap.add_argument("--policy", type=Path, required=True,
                    help="student artifact (*.safetensors), or a keyframe chain's folder (chain.json)")
    ap.add_argument("--label", default=DEFAULT_LABEL,
                    help="name of --policy in the report (e.g. joystick; a chain: its folder's name)")
    ap.add_argument("--baseline", default="", help="GETUP,JOYSTICK artifacts of the baseline composite")
    ap.add_argument("--teacher", default="", help="GETUP,JOYSTICK artifacts of the stitched teacher (experts); "
                    "fig5.1's default: the teacher the student's provenance names")
    ap.add_argument("--trials", type=int, default=None, help="trials per policy (default: the scenario's)")
    ap.add_argument("--seconds", type=float, default=None, help="sim seconds per trial (default: the scenario's)")
    ap.add_argument("--seed", type=int, default=None,
                    help="first trial seed (trial i uses seed + i; default: the scenario's, 0 or fig5.1's 62)")
    ap.add_argument("--jobs", type=int, default=MAX_JOBS, help=f"parallel trials, 1..{MAX_JOBS}")
    ap.add_argument("--out", type=Path, default=None, help="default: out/eval/<scenario>")
    ap.add_argument("--no-video", action="store_true", help="skip the mp4 (rendering costs ~0.1 s per frame)")
    ap.add_argument("--no-log", action="store_true", help="no LCM log per trial (default: OUT/logs/*.lcmlog)")
    ap.add_argument("--no-steer", action="store_true",
                    help="wall, puddle: a constant stick instead of the operator steering down the course")
    args = ap.parse_args(argv)
    plan = PLANS[args.scenario]
    args.trials = plan.default_trials if args.trials is None else args.trials
    args.seconds = plan.default_seconds if args.seconds is None else args.seconds
    if args.trials < 1:
        ap.error(f"--trials {args.trials}: need at least 1")
    if args.seconds <= 0:
        ap.error(f"--seconds {args.seconds}: must be > 0")
    if not 1 <= args.jobs <= MAX_JOBS:
        ap.error(f"--jobs {args.jobs}: must be 1..{MAX_JOBS}")
    args.seed = plan.seed0 if args.seed is None else args.seed
    if plan.name == "fig5.1" and not args.teacher:   # the seed's figure is teacher beside student
        try:
            args.teacher = distilled_from(args.policy)
        except ValueError as e:
            _refuse(str(e))
    if args.label == DEFAULT_LABEL and keyframe_chain.is_chain(args.policy):
        args.label = args.policy.resolve().name       # a shipped chain by its folder's name (getup_keyframe)
    controllers = [Controller(args.label, args.policy)]
    for flag, label in (("baseline", "baseline"), ("teacher", "teacher")):
        value = getattr(args, flag)
        if not value:
            continue
        parts = [p.strip() for p in value.split(",")]
        if len(parts) != 2 or not all(parts):
            ap.error(f"--{flag} {value!r}: expected GETUP.safetensors,JOYSTICK.safetensors")
        controllers.append(Controller(label, Path(parts[0]), Path(parts[1])))
    from common.artifact import artifact_problem
    for c in controllers:
        for p in (c.policy, c.upright):
            problem = None if p is None or keyframe_chain.is_chain(p) else artifact_problem(p)
            if problem:
                _refuse(f"policy artifact {problem}")
    args.out = args.out or ROOT / "out" / "eval" / args.scenario
    return args, plan, controllers


def main(argv=None) -> int:
    args, plan, controllers = parse_args(argv)
    if os.environ.get("T1_NETNS_INSIDE") != "1":
        print("sim_hil.eval: run inside the project network namespace (tools/netns, or make eval-*)", file=sys.stderr)
        return EXIT_USAGE
    from tqdm import tqdm

    from sim_hil.eval.report import trained_flags, trained_line, write_report
    print(trained_line(trained_flags(controllers)))
    args.out.mkdir(parents=True, exist_ok=True)
    video = None if args.no_video else args.out / "video.mp4"
    specs = plan.specs(args.trials, args.seconds, args.seed)
    if args.no_steer:
        specs = [replace(s, steer_heading_rad=None) for s in specs]
    jobs = []
    for i, spec in enumerate(specs):
        for c in controllers:
            record = str(video) if (video is not None and i == 0 and c is controllers[0]) else None
            log = None if args.no_log else str(args.out / "logs" / trial_log_name(spec, c.label))
            jobs.append((replace(spec, record=record, log=log), c, plan.finish_x_m, plan.segment_edges_x))
    started = time.monotonic()
    results, failures = [], []
    ctx = mp.get_context("spawn")          # a fresh interpreter per worker: no forked MuJoCo/LCM state
    slots = ctx.Manager().Queue()
    for w in range(args.jobs):
        slots.put(w)
    with ProcessPoolExecutor(args.jobs, mp_context=ctx, initializer=init_worker, initargs=(slots,)) as pool:
        futures = {pool.submit(run_job, job): job for job in jobs}
        for fut in tqdm(as_completed(futures), total=len(futures), desc=f"eval {plan.name}", unit="trial"):
            spec, c = futures[fut][:2]
            try:
                results.append(fut.result())
            except Exception as exc:  # noqa: BLE001 - one failed trial is reported, the rest still count
                failures.append(f"{c.label} seed {spec.seed}: {exc}")
    results.sort(key=lambda r: (r.controller, r.spec.seed))
    for f in failures:
        print(f"sim_hil.eval: trial FAILED: {f}", file=sys.stderr)
    if not results:
        return EXIT_FAILED
    command = "python -m sim_hil.eval " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    paths = write_report(args.out, plan, controllers, results, command, args.trials, args.seconds,
                         time.monotonic() - started, video)
    for name, path in paths.items():
        print(f"sim_hil.eval: {name:7s} {path}")
    return EXIT_FAILED if failures else EXIT_OK


if __name__ == "__main__":
    raise SystemExit(main())
