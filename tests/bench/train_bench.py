"""`make bench-train`: end-to-end PPO throughput (physics + learner), CPU backend vs MJX on the same CPU.

    python -m tests.bench.train_bench [--tasks joystick getup] [--updates N] [--quick]

For each task, two short `--preset cpu` PPO runs of the real training code (training/train.py, brax's
ppo.train, networks as shipped), one per backend, in this process one after the other, so both see the
same machine and load. A run's figure is the median of brax's per-epoch `training/sps` after the first
epoch (the first includes compilation), the same number `python -m training train` records. Printed:
env-steps/s of each backend, the CPU/MJX ratio, and issue 12's targets (≥ 8× MJX on CPU; joystick
≥ 5 000 and getup ≥ 3 000 env-steps/s on the 2-core machine). No evaluation rollouts are run.

MJX on the CPU compiles for minutes (getup's full-body contacts the longest); --quick measures the CPU
backend alone.
"""
from __future__ import annotations

import argparse
import tempfile
import time

TASK_STAGES = {"joystick": None, "getup": "stage2"}
TARGET_SPS = {"joystick": 5000.0, "getup": 3000.0}
TARGET_RATIO = 8.0
STEPS_PER_UPDATE = 256 * 4 * 20   # --preset cpu: batch_size · num_minibatches · unroll_length


def measure(task: str, backend: str, updates: int) -> tuple[float, float]:
    """(steady env-steps/s, wall s) of a fresh `--preset cpu` run of `updates`+1 epochs of one update."""
    from training import train
    with tempfile.TemporaryDirectory(prefix=f"bench_{task}_{backend}_") as out:
        t0 = time.monotonic()
        result = train.train(task, out, steps=STEPS_PER_UPDATE * (updates + 1), preset="cpu", backend=backend,
                             stage=TASK_STAGES[task], progress=False,
                             overrides=[f"ppo.checkpoint_every_steps={STEPS_PER_UPDATE}", "ppo.run_evals=False"])
        return result.env_steps_per_s, time.monotonic() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tasks", nargs="+", choices=tuple(TASK_STAGES), default=list(TASK_STAGES))
    ap.add_argument("--updates", type=int, default=3, help="timed PPO updates per run (after a warm-up one)")
    ap.add_argument("--quick", action="store_true", help="CPU backend only (no MJX compile)")
    args = ap.parse_args(argv)
    if args.updates < 1:
        ap.error(f"--updates {args.updates}: need at least 1")
    print(f"# PPO env-steps/s, --preset cpu, {args.updates} timed updates of {STEPS_PER_UPDATE} env steps")
    print(f"{'task':10s} {'cpu backend':>12s} {'mjx on cpu':>11s} {'ratio':>7s}   targets")
    for task in args.tasks:
        cpu, cpu_wall = measure(task, "cpu", args.updates)
        line = f"{task:10s} {cpu:12,.0f}"
        if args.quick:
            line += f" {'-':>11s} {'-':>7s}"
        else:
            mjx, mjx_wall = measure(task, "mjx", args.updates)
            line += f" {mjx:11,.0f} {cpu / mjx:6.1f}x"
        met = cpu >= TARGET_SPS[task]
        line += (f"   ≥ {TARGET_SPS[task]:,.0f} env-steps/s: {'met' if met else 'NOT met'}"
                 + ("" if args.quick else f"; ≥ {TARGET_RATIO:g}x: {'met' if cpu / mjx >= TARGET_RATIO else 'NOT met'}")
                 + f"   (wall: cpu {cpu_wall:.0f} s" + ("" if args.quick else f", mjx {mjx_wall:.0f} s") + ")")
        print(line, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
