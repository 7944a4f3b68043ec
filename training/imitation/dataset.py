"""DAgger's aggregated data set on disk: per round one file of observations and the planner's joint targets,
float16 (the observation's joint velocities to 0.01 rad/s and targets to 1e-3 rad; the fit reads what is stored,
so a run resumed on another machine fits the same numbers). Nothing derivable is stored: the labels' actions
come from the targets through the learner's action map. Round 0 is the planner's stored demonstrations, read from
their folder (rounded the same way, so the fit does not depend on where they came from)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from training.planner import demos as planner_demos

DTYPE = np.float16


def round_path(folder: Path, k: int) -> Path:
    return Path(folder) / f"round_{k:02d}.npz"


def policy_path(folder: Path, k: int) -> Path:
    """Where a round rolled out by another policy than the learner keeps that policy's artifact."""
    return Path(folder) / f"policy_{k:02d}.safetensors"


def kept_policies(folder: Path) -> list[Path]:
    """The policies rounds in `folder` were rolled out by (policy_path), in round order."""
    return sorted(Path(folder).glob("policy_*.safetensors"))


def demonstration_pairs(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """(obs (N, 52), q_des (N, 23) [rad]) of every step of the planner's demonstrations in `folder`."""
    paths = sorted(Path(folder).glob("demo_*.npz"), key=lambda p: int(p.stem.split("_")[1]))
    if not paths:
        raise ValueError(f"{folder}: no planner demonstrations (demo_<seed>.npz)")
    obs, q = [], []
    for path in paths:
        d = planner_demos.load(path)
        obs.append(d.obs[:len(d.targets)])
        q.append(d.targets)
    return _stored(np.concatenate(obs)), _stored(np.concatenate(q))


def _stored(x: np.ndarray) -> np.ndarray:
    """As a round's file holds it, back in float32."""
    return x.astype(DTYPE).astype(np.float32)


def save_round(folder: Path, k: int, obs: np.ndarray, q_des: np.ndarray) -> Path:
    if len(obs) != len(q_des) or not np.all(np.isfinite(obs)) or not np.all(np.isfinite(q_des)):
        raise ValueError(f"round {k}: observations and labels must be finite and as many")
    path = round_path(folder, k)
    Path(folder).mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, obs=obs.astype(DTYPE), q_des=q_des.astype(DTYPE))
    return path


def load_round(folder: Path, k: int) -> tuple[np.ndarray, np.ndarray]:
    path = round_path(folder, k)
    try:
        z = np.load(path)
        obs, q = z["obs"].astype(np.float32), z["q_des"].astype(np.float32)
    except (OSError, KeyError, ValueError) as e:
        raise ValueError(f"{path}: not a DAgger round's data ({e})") from e
    if obs.ndim != 2 or q.ndim != 2 or len(obs) != len(q):
        raise ValueError(f"{path}: obs {obs.shape} and q_des {q.shape} do not pair up")
    return obs, q


def aggregate(folder: Path, demos: Path, rounds: int, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Rounds first … rounds − 1 together, round 0 the demonstrations in `demos`."""
    if not 0 <= first < rounds:
        raise ValueError(f"{folder}: no rounds from {first} on (it holds rounds 0 … {rounds - 1})")
    parts = [demonstration_pairs(demos)] if first == 0 else []
    parts += [load_round(folder, k) for k in range(max(first, 1), rounds)]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
