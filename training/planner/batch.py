"""Plan rises for a list of seeds into one folder: the planner's batch, in this process or in worker processes
(a module of its own, not __main__, so that spawned workers can import its functions)."""
from __future__ import annotations

import ctypes
import json
import multiprocessing
import signal
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

import numpy as np

from training.planner import demos  # first: its renderer picks the offscreen GL before mujoco loads

# isort: split
from training import envs
from training.core.overrides import apply_overrides
from training.planner import config as planner_config
from training.planner.mppi import Planner


def build(overrides: list[str]):
    """(config, getup env on the CPU backend, planner): the env gives the training physics and the starts."""
    cfg = planner_config.default_config()
    apply_overrides({"planner": cfg}, overrides)
    env = envs.make("getup_kneel", config_overrides={"backend": "cpu", "fallen.bank_starts": 1})
    fields = env.manifest_fields()
    planner = Planner(env.cpu_physics, cfg, np.asarray(fields["default_pose"]), np.asarray(fields["action_scale"]))
    return cfg, env, planner


_worker = None      # a worker process's planner (built once per process)
PR_SET_PDEATHSIG = 1    # <sys/prctl.h>


def _init_worker(overrides: list[str]) -> None:
    global _worker
    end_with_parent()
    _worker = build(overrides)


def end_with_parent() -> None:
    """Linux's PR_SET_PDEATHSIG: a worker gets SIGTERM when the batch that spawned it dies, instead of planning
    on as an orphan (a worker notices a dead pool only when it asks for its next seed)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):
        pass                        # not Linux: a killed batch's workers end with their seed


def _plan(seed: int, out: Path) -> Path:
    _, env, planner = _worker
    qpos, qvel = (a[0].astype(np.float64) for a in env.fallen_starts(1, seed))
    return demos.save(planner.rise(qpos, qvel, planner.default_pose, seed), out)


def run(seeds: list[int], out: Path, overrides: list[str], max_minutes: float | None = None,
        log=print, jobs: int = 1) -> dict:
    global _worker
    if jobs < 1:
        raise ValueError(f"--jobs must be at least 1, got {jobs}")
    cfg, env, planner = _worker = build(overrides)
    out.mkdir(parents=True, exist_ok=True)
    old = out / demos.REPORT
    if old.exists() and json.loads(old.read_text())["config"] != cfg.to_dict():
        raise ValueError(f"{out}: its demonstrations were planned with another config; use a new folder")
    rows = []
    started = time.monotonic()

    def add(seed: int) -> None:
        qpos = env.fallen_starts(1, seed)[0][0].astype(np.float64)
        rows.append(demos.row(demos.load(out / f"demo_{seed}.npz"), demos.start_side(qpos)))
        demos.write_report(out, cfg, rows)
        r = rows[-1]
        log(f"seed {seed:4d} {r['side']:9s} gate {r['gate_time_s'] if r['gate_time_s'] is not None else '–':>5} s  "
            f"held {r['held_share']:.2f}  end trunk {r['final_trunk_m']:.3f} m up_z {r['final_up_z']:.4f}  "
            f"{r['energy_J']:.0f} J  {r['cpu_s']:.0f} CPU s")

    def out_of_time() -> bool:
        return max_minutes is not None and time.monotonic() - started > 60.0 * max_minutes

    todo = [s for s in seeds if not (out / f"demo_{s}.npz").exists()]
    for seed in seeds:
        if seed not in todo:
            add(seed)
    if jobs == 1:
        for seed in todo:
            if out_of_time():
                break
            _plan(seed, out)
            add(seed)
    else:
        ctx = multiprocessing.get_context("spawn")      # a fresh interpreter: no forked JAX or MuJoCo state
        with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_init_worker, initargs=(overrides,)) as pool:
            pending, queue = {}, list(todo)
            while queue or pending:
                while queue and len(pending) < jobs and not out_of_time():
                    seed = queue.pop(0)
                    pending[pool.submit(_plan, seed, out)] = seed
                if not pending:
                    break
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for f in done:
                    f.result()
                    add(pending.pop(f))
    if len(rows) < len(seeds):
        log(f"planner: --max-minutes {max_minutes:g} reached; {len(rows)} of {len(seeds)} seeds planned")
    for side in ("face_down", "on_back"):      # each side's strip: its lowest seed that met the gate, else its lowest
        shown = sorted((r for r in rows if r["side"] == side), key=lambda r: (r["gate_time_s"] is None, r["seed"]))
        if shown:
            demo = demos.load(out / f"demo_{shown[0]['seed']}.npz")
            demos.frame_strip(planner.model, demo, out / f"strip_{side}.png")
    return demos.write_report(out, cfg, rows) if rows else {}
