"""Seeded fallen start states for the getup tasks, precomputed on the host in C MuJoCo.

`sim_hil.model.fallen_state(model, seed)` drops the robot from a random pose and returns the settled
lying state; it is deterministic per seed, so a bank of starts is (seed, seed + 1, ...). Results are
cached in memory per seed, so a second env (or a test) asking for the same seeds pays nothing.
"""
from __future__ import annotations

import functools

import numpy as np

from sim_hil import model as t1model


@functools.lru_cache(maxsize=1)
def _model():
    return t1model.load_model()


@functools.lru_cache(maxsize=None)
def _one(seed: int) -> tuple[np.ndarray, np.ndarray]:
    qpos, qvel = t1model.fallen_state(_model(), seed)
    qpos.flags.writeable = False
    qvel.flags.writeable = False
    return qpos, qvel


def fallen_states(num: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos [num, nq], qvel [num, nv]) of fallen states for seeds seed, seed + 1, ..., seed + num − 1."""
    if isinstance(num, bool) or not isinstance(num, (int, np.integer)) or num < 1:
        raise ValueError(f"fallen_states: num must be a positive int, got {num!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"fallen_states: seed must be a non-negative int, got {seed!r}")
    states = [_one(int(seed) + i) for i in range(int(num))]
    return np.stack([s[0] for s in states]), np.stack([s[1] for s in states])
