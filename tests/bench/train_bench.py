"""`make bench-train`: PPO throughput on the CPU backend against the raw physics rate, where the rest goes, and
MJX on the same CPU.

    python -m tests.bench.train_bench [--tasks joystick getup_stand unified] [--updates N] [--quick]

For each task, in this process one after the other (same machine, same load):
* the raw physics rate M: the CPU backend's batched C physics alone (firmware motor law and R6 in MuJoCo's
  control callback, 10 substeps a control step) for the preset's envs at the task's own starts, targets
  changing every control step; the time inside `Batch.step` only;
* a short `--preset cpu` PPO run of the real training code (training/ppo/train.py, brax's ppo.train, networks as
  shipped): N, the median of brax's per-epoch `training/sps` after the first (which includes compilation),
  the number `python -m training train` records; R = N / M (target: R ≥ 0.8 for getup_stand and unified);
* the run's profile: the shares of a steady env step's wall time spent in the C physics and in the host
  callback's copies (cpu_backend.PROFILE), in the env's JAX code, the policy pass and PPO's update (each timed
  alone at the run's sizes: train_profile.py), the rest (GAE, normaliser, PPO's loop); and each core's idle
  share over the whole run (/proc/stat; the first epoch's compilation is mostly one core);
* without --quick, the same PPO run on MJX (it compiles for minutes on a CPU) and the CPU/MJX ratio.
* the planner as DAgger's expert (tests/bench/planner_bench.py): its env-steps/s against the raw physics rate of
  the same batches, and the CPU seconds per label.
No evaluation rollouts are run.
"""
from __future__ import annotations

import argparse
import tempfile
import time

import numpy as np

TASKS = ("joystick", "getup_stand", "unified")
TARGET_SHARE = {"getup_stand": 0.8, "unified": 0.8}      # of the raw physics rate
TARGET_MJX_RATIO = 8.0            # the CPU backend's PPO rate over MJX's on the same CPU
STEPS_PER_UPDATE = 256 * 4 * 20   # --preset cpu: batch_size · num_minibatches · unroll_length
RAW_CONTROL_STEPS = 40            # control steps of the raw-physics measurement (after one warm-up step)
RAW_TARGET_SPREAD = 0.3           # targets: default pose ± this × the action scale, new every control step


def _cpu_jiffies() -> np.ndarray:
    """(cores, [idle, total]) jiffies from /proc/stat."""
    rows = [ln.split() for ln in open("/proc/stat") if ln.startswith("cpu") and ln[3].isdigit()]
    return np.array([[int(r[4]) + int(r[5]), sum(int(x) for x in r[1:])] for r in rows], dtype=np.float64)


def raw_physics_rate(task: str, num_envs: int, seed: int = 0) -> float:
    """Env-steps/s of the C physics alone (see the module docstring)."""
    import jax

    from training import envs
    from training.envs import cpu_backend
    env = envs.make(task, config_overrides={"backend": "cpu"})
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(seed), num_envs))
    qpos, qvel = np.asarray(state.data.qpos), np.asarray(state.data.qvel)
    warm, t = np.zeros_like(qvel), np.zeros(num_envs, np.float32)
    fields = env.manifest_fields()
    default, scale = np.asarray(fields["default_pose"]), np.asarray(fields["action_scale"])
    last = qpos[:, 7:7 + default.size]
    rng = np.random.default_rng(seed)
    for i in range(RAW_CONTROL_STEPS + 1):
        if i == 1:
            cpu_backend.PROFILE.reset()       # the first step made the batch
        q_des = default + scale * rng.uniform(-RAW_TARGET_SPREAD, RAW_TARGET_SPREAD, (num_envs, default.size))
        out = env.cpu_physics.host_step(t, qpos, qvel, warm, q_des.astype(np.float32), last)
        t, qpos, qvel, warm, last = out[0], out[1], out[2], out[3], out[-1]
    return cpu_backend.PROFILE.env_steps / cpu_backend.PROFILE.physics_s


def ppo_run(task: str, backend: str, updates: int) -> dict:
    """A fresh `--preset cpu` run of `updates`+1 epochs of one update: its steady env-steps/s, wall s, and (CPU
    backend) its profile."""
    from training.envs import cpu_backend
    from training.ppo import train
    cpu_backend.PROFILE.reset()
    jiffies, t0 = _cpu_jiffies(), time.monotonic()
    with tempfile.TemporaryDirectory(prefix=f"bench_{task}_{backend}_") as out:
        result = train.train(task, out, steps=STEPS_PER_UPDATE * (updates + 1), preset="cpu", backend=backend,
                             progress=False,
                             overrides=[f"ppo.checkpoint_every_steps={STEPS_PER_UPDATE}", "ppo.run_evals=False"])
    d = _cpu_jiffies() - jiffies
    p, sps = cpu_backend.PROFILE, result.env_steps_per_s
    per_step = (lambda s: s / p.env_steps * sps) if p.env_steps else (lambda s: float("nan"))
    return {"sps": sps, "wall_s": time.monotonic() - t0, "physics": per_step(p.physics_s),
            "copies": per_step(p.copies_s), "idle": d[:, 0] / np.maximum(d[:, 1], 1.0)}


def main(argv=None) -> int:
    from tests.bench import train_profile
    from training.ppo import configs
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tasks", nargs="+", choices=(*TASKS, "planner"), default=[*TASKS, "planner"],
                    help="PPO tasks, and `planner`: DAgger's expert (tests/bench/planner_bench.py)")
    ap.add_argument("--updates", type=int, default=3, help="timed PPO updates per run (after a warm-up one)")
    ap.add_argument("--quick", action="store_true", help="CPU backend only (no MJX compile)")
    args = ap.parse_args(argv)
    if args.updates < 1:
        ap.error(f"--updates {args.updates}: need at least 1")
    print(f"# --preset cpu, {args.updates} timed PPO updates of {STEPS_PER_UPDATE} env steps; shares of a steady "
          "env step's wall time; idle per core over the whole run")
    for task in [t for t in args.tasks if t != "planner"]:
        raw = raw_physics_rate(task, configs.ppo_config(task, "cpu").num_envs)
        run = ppo_run(task, "cpu", args.updates)
        share = run["sps"] / raw
        target = TARGET_SHARE.get(task)
        verdict = f"   target ≥ {target:g}: {'met' if share >= target else 'NOT met'}" if target else ""
        print(f"{task:9s} PPO {run['sps']:,.0f} env-steps/s = {share:.2f} of the raw physics rate ({raw:,.0f})"
              + verdict)
        parts = {k: s * run["sps"] for k, s in train_profile.profile(task).items()}
        rest = 1.0 - run["physics"] - run["copies"] - sum(parts.values())
        print(f"{'':9s} physics {run['physics']:.0%}, callback copies {run['copies']:.0%}, "
              + "".join(f"{k} {v:.0%}, " for k, v in parts.items()) + f"rest {rest:.0%}; idle per core "
              f"{', '.join(f'{x:.0%}' for x in run['idle'])}; wall {run['wall_s']:.0f} s", flush=True)
        if not args.quick:
            mjx = ppo_run(task, "mjx", args.updates)
            ratio = run["sps"] / mjx["sps"]
            print(f"{'':9s} MJX on this CPU {mjx['sps']:,.0f} env-steps/s: the CPU backend {ratio:.1f}x, target "
                  f"≥ {TARGET_MJX_RATIO:g}x: {'met' if ratio >= TARGET_MJX_RATIO else 'NOT met'} "
                  f"(wall {mjx['wall_s']:.0f} s)", flush=True)
    if "planner" in args.tasks:
        from tests.bench.planner_bench import planner_row
        print(planner_row(), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
