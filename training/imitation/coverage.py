"""The teacher's own rises: DAgger's expert (the planner, its candidates the policy's proposals beside its own warm
start, expert.Teacher; or with expert.best_of_k.k > 0 best-of-K rises of the policy) acting from fallen starts for
the whole rollout. How often it meets §4.8's gate in the
kneeling posture is how far the labels can lift the learner (the planner's coverage); every step costs what one
label does, so 200 seeds are affordable where the planner's own rises (training/planner/) are not.

    python -m training.imitation.coverage --policy ARTIFACT --out FILE.json [--seeds N] [--first-seed S]
                                          [--seconds T] [--lying SIDE] [--jobs J] [--config key=value ...]

The starts are the batch evaluation's (fallen seeds S … S + N − 1, as training/evaluation/batch.py draws them), so its
share compares with the policy's own `evaluate` row. They run in chunks of CHUNK robots, each seeded by its first
seed: the report does not depend on --jobs (one worker process per job)."""
from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from common import events
from training.imitation import best_of_k, dagger, dataset
from training.imitation.campaign import build
from training.imitation.learner import load_learner, new_learner
from training.planner.batch import end_with_parent
from training.planner.demos import start_side

CHUNK = 25       # robots planned in one batch


def rises(teacher, policy, qpos: np.ndarray, qvel: np.ndarray, seconds: float, rng: np.random.Generator) -> dict:
    """The teacher's rises from the starts (qpos, qvel), `seconds` long: per robot the first time [s] the gate
    held in the kneeling posture (nan: never) and the longest it held [s]."""
    p = teacher.p
    robots, plans, waypoint = teacher.start(qpos, qvel)
    seg = int(teacher.cfg.takeover_replans) * p.replan_knots * p.spk
    steps = int(round(seconds / p.ctrl_dt))
    gate = []
    for _ in range(0, steps, seg):
        out = teacher.takeover(robots, plans, waypoint, policy, rng)
        gate.append(out["gate"])
        plans, waypoint = out["plans"], out["waypoint"]
    gate = np.concatenate(gate)[:steps].T                     # (n, steps): after each step
    first = np.where(gate.any(axis=1), (np.argmax(gate, axis=1) + 1) * p.ctrl_dt, np.nan)
    held = np.array([events.longest_run(g) * p.ctrl_dt for g in gate])
    return {"gate_time_s": first, "held_s": held}


_worker = None      # a worker process's (teacher, env, policy)


def _setup(overrides: list[str], policy_path: str):
    cfg, teacher, env = build(overrides)
    obs0, _ = dataset.demonstration_pairs(dagger.DEFAULT_DEMOS)
    p = teacher.p
    template = new_learner(obs0, list(cfg.fit.hidden_layer_sizes), int(cfg.fit.seed), env.manifest_fields(),
                           p.lo, p.hi)
    return cfg, teacher, env, load_learner(Path(policy_path), template)


def _init_worker(overrides: list[str], policy_path: str) -> None:
    global _worker
    end_with_parent()
    _worker = _setup(overrides, policy_path)


def _chunk(qpos: np.ndarray, qvel: np.ndarray, first_seed: int, seconds: float) -> tuple[dict, float]:
    cfg, teacher, _, learner = _worker
    cpu0 = time.process_time()
    rng = np.random.default_rng([int(cfg.seed), first_seed])
    if int(cfg.expert.best_of_k.k) > 0:
        got = best_of_k.collect(teacher, learner.targets, qpos, qvel, cfg.expert.best_of_k, seconds, rng)
    else:
        got = rises(teacher, learner.targets, qpos, qvel, seconds, rng)
    return got, time.process_time() - cpu0


def run(policy: Path, seeds: int, first_seed: int, seconds: float, overrides: list[str], lying: str = "",
        jobs: int = 1, log=print) -> dict:
    """The report of the teacher's rises (module docstring)."""
    global _worker
    if seeds < 1 or jobs < 1 or seconds <= 0:
        raise ValueError(f"--seeds, --jobs and --seconds must be positive, got {seeds}, {jobs}, {seconds:g}")
    if lying and lying not in events.LYING_SIDES:
        raise ValueError(f"--lying must be one of {', '.join(events.LYING_SIDES)}, got {lying!r}")
    if not Path(policy).is_file():
        raise ValueError(f"--policy {policy}: no such artifact")
    _worker = _setup(overrides, str(policy))
    cfg, teacher, env, _ = _worker
    qpos, qvel = (a.astype(np.float64) for a in env.fallen_starts(seeds, first_seed))
    sides = np.array([start_side(q) for q in qpos])
    ids = np.arange(first_seed, first_seed + seeds)
    keep = sides == lying if lying else np.ones(seeds, bool)
    qpos, qvel, sides, ids = qpos[keep], qvel[keep], sides[keep], ids[keep]
    parts = [slice(i, i + CHUNK) for i in range(0, len(ids), CHUNK)]
    args = [(qpos[s], qvel[s], int(ids[s][0]), seconds) for s in parts]
    started = time.monotonic()
    if jobs == 1:
        done = [_chunk(*a) for a in args]
    else:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_init_worker,
                                 initargs=(overrides, str(policy))) as pool:
            done = list(pool.map(_chunk, *zip(*args)))
    gate_s = np.concatenate([d[0]["gate_time_s"] for d in done])       # best-of-K: the chosen rise's
    held_s = np.concatenate([d[0]["held_s"] for d in done])
    report = {"policy": str(policy), "seeds": [int(first_seed), int(first_seed + seeds)], "seconds": seconds,
              "lying": lying or None, "expert": cfg.expert.to_dict(), "planner": teacher.p.cfg.to_dict(),
              "cpu_s": round(sum(d[1] for d in done), 1), "minutes": round((time.monotonic() - started) / 60, 1),
              "summary": summarise(gate_s, held_s, sides),
              **({"policy_met_gate": sum(d[0]["policy_met_gate"] for d in done)}
                 if int(cfg.expert.best_of_k.k) > 0 else {}),
              "rises": [{"seed": int(i), "side": str(s), "gate_time_s": None if np.isnan(g) else round(float(g), 2),
                         "held_s": round(float(h), 2)} for i, s, g, h in zip(ids, sides, gate_s, held_s)]}
    log(json.dumps(report["summary"]))
    return report


def summarise(gate_s: np.ndarray, held_s: np.ndarray, sides: np.ndarray) -> dict:
    """Per lying side and in all: rises, the share meeting the gate, and of those the share holding it
    events.KNEEL_HOLD_S (the batch evaluation's figures)."""
    out = {}
    for side in (*events.LYING_SIDES, "all"):
        m = sides == side if side != "all" else np.ones(len(sides), bool)
        if m.any():
            met = ~np.isnan(gate_s[m])
            out[side] = {"rises": int(m.sum()), "met_gate": int(met.sum()), "share": round(float(met.mean()), 3),
                         "held": round(float(np.mean(held_s[m][met] >= events.KNEEL_HOLD_S)), 3) if met.any()
                         else None}
    return out


def main(argv=None) -> int:
    a = argparse.ArgumentParser(prog="python -m training.imitation.coverage", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("--policy", required=True, type=Path, help="the learner artifact whose proposals the teacher uses")
    a.add_argument("--out", required=True, type=Path, help="the report (JSON)")
    a.add_argument("--seeds", type=int, default=200, help="fallen starts")
    a.add_argument("--first-seed", type=int, default=0)
    a.add_argument("--seconds", type=float, default=8.0, help="each rise's length [s] (§4.8: within 8 s)")
    a.add_argument("--lying", default="", help="only the starts lying this way (face_down, on_back, side)")
    a.add_argument("--jobs", type=int, default=1, help="worker processes")
    a.add_argument("--config", action="append", default=[], metavar="KEY=VALUE",
                   help="a DAgger setting (expert.…) or, prefixed planner., the planner's; repeatable")
    args = a.parse_args(argv)
    try:
        report = run(args.policy, args.seeds, args.first_seed, args.seconds, args.config, args.lying, args.jobs)
    except ValueError as e:
        print(f"coverage: {e}", file=sys.stderr)
        return 2
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
