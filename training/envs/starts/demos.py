"""Starts along the planner's rises to the kneel (backplay): a share of the getup env's fallen starts is instead
a state of a demonstration (qpos and qvel: the robot mid-rise, moving), drawn from the last `window_s` of it up to
its end (a demonstration that met §4.8's gate: the planner holds the gate to its end, so the narrowest window
starts at the goal) or, for one that never met the gate, up to its arrival at the kneel (or not at all:
gated_only). A recipe widens the window stage by stage as stage 1 succeeds from it, as Backplay and
"Montezuma's Revenge from a single demonstration" move the start back along the demonstration.

The demonstrations are a folder the planner wrote (`python -m training.planner`, training/planner/demos.py:
demo_<seed>.npz with per-step qpos, qvel, trunk_height, kneeling and gate). A demonstration arrives at the first
step with the trunk at the §4.8 gate's height in the kneeling posture; one that did neither is not used."""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
from ml_collections import config_dict

from common import events
from training.envs.starts.bank import frozen_bank

REPO_ROOT = Path(__file__).resolve().parents[3]
DEMO_GLOB = "demo_*.npz"
ARRAYS = ("qpos", "qvel", "trunk_height", "kneeling", "gate", "ctrl_dt")   # of each demonstration file (per step; [s])
ARRIVAL_HEIGHT_M = events.KNEEL_GATE_HEIGHT_M - events.KNEEL_GATE_HEIGHT_TOL_M


def demo_config() -> config_dict.ConfigDict:
    """This share of the fallen starts is a demonstration state from `folder` (repository-relative or
    absolute), at most `window_s` [s] before its window's end; `bank_starts` states, drawn with `seed`.
    gated_only: only the demonstrations that met the gate (Backplay's demonstrations of success: a rise the
    planner could not finish is a start the learner has no example to finish from)."""
    return config_dict.create(prob=0.0, folder="", window_s=0.5, bank_starts=1024, seed=400_000, gated_only=False)


def demo_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    return demo_bank(str(group.folder), float(group.window_s), int(group.bank_starts), int(group.seed),
                     bool(group.gated_only))


def at_kneel(trunk_height: np.ndarray, kneeling: np.ndarray) -> np.ndarray:
    """Per step: the trunk at the gate's height in the kneeling posture (the gate then asks for it upright)."""
    return (np.asarray(trunk_height) >= ARRIVAL_HEIGHT_M) & np.asarray(kneeling, bool)


def arrival_step(trunk_height: np.ndarray, kneeling: np.ndarray) -> int | None:
    """The first step at the kneel, or None."""
    hit = np.flatnonzero(at_kneel(trunk_height, kneeling))
    return int(hit[0]) if hit.size else None


def met_gate(gate: np.ndarray, kneeling: np.ndarray) -> bool:
    """The demonstration met §4.8's gate in the kneeling posture."""
    return bool(np.any(np.asarray(gate, bool) & np.asarray(kneeling, bool)))


def window_end(trunk_height: np.ndarray, kneeling: np.ndarray, gate: np.ndarray) -> int | None:
    """The step a demonstration's window ends at: its last when it met the gate in the kneeling posture, else its
    arrival at the kneel, else None."""
    return len(trunk_height) - 1 if met_gate(gate, kneeling) else arrival_step(trunk_height, kneeling)


def demo_seeds(folder) -> list[int]:
    """The fallen seeds of a folder's demonstrations (demo_<seed>.npz: each starts at that seed's fallen state)."""
    return sorted(int(f.stem.split("_", 1)[1]) for f in Path(folder).glob(DEMO_GLOB))


@functools.lru_cache(maxsize=4)
def demo_pool(folder: str, window_s: float, gated_only: bool = False) -> dict[str, np.ndarray]:
    """The used demonstrations' states, whole, and the rows a start may be drawn from. Keys: `qpos`, `qvel`
    (R, ·) every step of every used demonstration, concatenated; `window` (W,) the rows of the last window_s before
    each window's end; `last` (R,) each row's demonstration's last row (a reference holds there after it);
    `ctrl_dt` () their control step [s]. Cached (read-only arrays)."""
    if window_s <= 0:
        raise ValueError(f"demo_starts: window_s must be > 0, got {window_s}")
    path = Path(folder) if Path(folder).is_absolute() else REPO_ROOT / folder
    files = sorted(path.glob(DEMO_GLOB))
    if not files:
        raise ValueError(f"demo_starts.folder {folder!r}: no {DEMO_GLOB} there "
                         "(python -m training.planner writes them)")
    qpos, qvel, window, last, rows, dts = [], [], [], [], 0, set()
    for f in files:
        try:
            with np.load(f) as z:
                demo = {k: z[k] for k in ARRAYS}
        except (OSError, KeyError, ValueError) as e:
            raise ValueError(f"demo_starts: {f} is not a planner demonstration ({e})") from e
        end = window_end(demo["trunk_height"], demo["kneeling"], demo["gate"])
        if gated_only and not met_gate(demo["gate"], demo["kneeling"]):
            end = None
        if end is None:
            continue
        dts.add(float(demo["ctrl_dt"]))
        back = int(round(window_s / float(demo["ctrl_dt"])))
        n = len(demo["qpos"])
        qpos.append(demo["qpos"])
        qvel.append(demo["qvel"])
        window.append(rows + np.arange(max(0, end - back), end + 1))
        last.append(np.full(n, rows + n - 1))
        rows += n
    if not qpos:
        raise ValueError(f"demo_starts.folder {folder!r}: none of its {len(files)} demonstrations "
                         f"{'met the gate' if gated_only else 'reached the kneel'}")
    if len(dts) > 1:
        raise ValueError(f"demo_starts.folder {folder!r}: its demonstrations mix control steps {sorted(dts)} s")
    pool = {"qpos": np.concatenate(qpos).astype(np.float32), "qvel": np.concatenate(qvel).astype(np.float32),
            "window": np.concatenate(window), "last": np.concatenate(last), "ctrl_dt": np.asarray(dts.pop())}
    for array in pool.values():
        array.flags.writeable = False
    return pool


def bank_rows(folder: str, window_s: float, num_starts: int, seed: int, gated_only: bool = False) -> np.ndarray:
    """The pool rows (demo_pool) of the bank's `num_starts` starts, drawn uniformly from the windows."""
    if num_starts < 1:
        raise ValueError(f"demo_starts: bank_starts must be ≥ 1, got {num_starts}")
    window = demo_pool(folder, window_s, gated_only)["window"]
    return window[np.random.default_rng(seed).integers(0, len(window), num_starts)]


@functools.lru_cache(maxsize=4)
def demo_bank(folder: str, window_s: float, num_starts: int, seed: int,
              gated_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) of `num_starts` states drawn uniformly from the last window_s before each window's end (all
    used demonstrations' states pooled; gated_only: of those that met the gate). Cached (read-only arrays)."""
    pool = demo_pool(folder, window_s, gated_only)
    return frozen_bank(bank_rows(folder, window_s, num_starts, seed, gated_only), pool["qpos"], pool["qvel"])
