"""The physics backend a run, DAgger run or evaluation uses unless told."""
from __future__ import annotations

import jax


def default_backend() -> str:
    """mjx where JAX sees a GPU, else the CPU backend (MuJoCo C on all cores)."""
    return "mjx" if any(d.platform == "gpu" for d in jax.devices()) else "cpu"
