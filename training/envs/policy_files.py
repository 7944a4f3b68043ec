"""Where a policy's parameters are read from, for the envs' start banks and the teacher: a brax checkpoint folder
or a run directory (its newest checkpoint); training/core/checkpoints.py writes what this reads. Artifacts are read by
common/artifact.py."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np
from brax.training import checkpoint as brax_checkpoint

from common.artifact import read_artifact

RUN_STATE = "run_state.json"
CHECKPOINT_DIR = "checkpoints"
ACTIVATION = "swish"  # brax's PPO/BC default (flax linen.swish); the artifact's activation must match


def list_checkpoints(run_dir) -> list[Path]:
    root = Path(run_dir) / CHECKPOINT_DIR
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir() if p.is_dir() and p.name.isdigit())


def resolve_checkpoint(path) -> Path:
    """A checkpoint folder, or a run directory (→ its newest checkpoint)."""
    path = Path(path)
    if (path / RUN_STATE).exists() or (path / CHECKPOINT_DIR).is_dir():
        found = list_checkpoints(path)
        if not found:
            raise FileNotFoundError(f"{path}: run directory without checkpoints")
        return found[-1]
    if path.is_dir() and path.name.isdigit():
        return path
    raise FileNotFoundError(f"{path}: neither a checkpoint folder (<steps>/) nor a run directory with "
                            f"{CHECKPOINT_DIR}/")


def load_checkpoint(path) -> list:
    """[normalizer_state, policy_params, (value_params)] as numpy trees (brax checkpoint.load)."""
    return brax_checkpoint.load(resolve_checkpoint(path).resolve())


def artifact_params(artifact: Path) -> tuple[dict, np.ndarray, np.ndarray, dict]:
    """(brax policy params, observation mean, std, manifest) of an artifact of `export` (its layers are brax's,
    the scale half included): brax_policy_layers inverted."""
    layers, mean, std, manifest = read_artifact(Path(artifact))
    params = {f"hidden_{i}": {"kernel": np.ascontiguousarray(w.T), "bias": b} for i, (w, b) in enumerate(layers)}
    return {"params": params}, np.asarray(mean, np.float32), np.asarray(std, np.float32), manifest


def brax_policy_layers(policy_params: Mapping[str, Any]) -> list[tuple[np.ndarray, np.ndarray]]:
    """brax MLP params {'params': {'hidden_i': {'kernel' (in, out), 'bias'}}} → [(W (out, in), b)]."""
    inner = policy_params.get("params", policy_params)
    names = sorted(inner, key=lambda n: int(n.split("_")[-1]) if n.startswith("hidden_") else -1)
    if not names or any(not n.startswith("hidden_") for n in names):
        raise ValueError(f"policy_params: expected only brax MLP layers hidden_0..hidden_N, got {sorted(inner)} "
                         "(layer norm / separate-std policies are not supported by schema 1)")
    if [int(n.split("_")[-1]) for n in names] != list(range(len(names))):
        raise ValueError(f"policy_params: layer names are not contiguous: {names}")
    layers = []
    for n in names:
        if set(inner[n]) != {"kernel", "bias"}:
            raise ValueError(f"policy_params: {n} must hold exactly kernel and bias, has {sorted(inner[n])}")
        kernel = np.asarray(inner[n]["kernel"], dtype=np.float32)
        layers.append((np.ascontiguousarray(kernel.T), np.asarray(inner[n]["bias"], dtype=np.float32)))
    return layers
