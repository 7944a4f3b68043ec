"""Experts as jax functions and the observation adapter.

An expert is loaded from a policy artifact or a PPO checkpoint (both become the artifact's numbers:
layers, normaliser, obs terms), so a teacher or a rollout runs exactly what the runtime would run.
Observations are vectors of named terms (common/observation.py); `TermAdapter` maps one term layout onto
another by slicing, and fills the two terms a getup env does not produce with the values they have while
standing still: command = 0 and the gait phase frozen at its initial value (the gait clock does not advance
while ‖command‖ < phase_freeze_command_norm, policies/ARTIFACT.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import jax.numpy as jnp
import numpy as np

from common import model as t1model
from common import observation as obsdef
from common.artifact import read_artifact
from training.envs import base
from training.envs.getup_base import GETUP_ACTION_SCALE_RAD
from training.envs.policy_files import ACTIVATION, brax_policy_layers, load_checkpoint

WAIST_OBS_KEY = "waist_height"
STUDENT_OBS_KEY = "state"


@dataclass(frozen=True)
class Expert:
    name: str
    layers: tuple            # ((W (out, in), b), ...) float32 numpy
    obs_mean: np.ndarray
    obs_std: np.ndarray
    activation: str
    obs_terms: tuple         # ((name, size), ...)
    action_scale: np.ndarray  # (23,) rad per unit action: target = default pose + action_scale · tanh(loc)

    def loc(self, obs, xp=None):
        """The pre-tanh mean (brax tanh-normal `loc`) for raw observations in this expert's term layout."""
        xp = xp or jnp
        out = obsdef.policy_forward(self.layers, obs, xp.asarray(self.obs_mean), xp.asarray(self.obs_std),
                                    self.activation, "linear", xp=xp)
        return out[..., :obsdef.NUM_JOINTS]


def _terms_for_size(size: int, source) -> tuple:
    matches = [t for t in (obsdef.TERMS_UNION, obsdef.TERMS_GETUP) if obsdef.observation_size(t) == size]
    if not matches:
        raise ValueError(f"{source}: policy input size {size} matches neither the joystick/student terms "
                         f"({obsdef.observation_size(obsdef.TERMS_UNION)}) nor the getup terms "
                         f"({obsdef.observation_size(obsdef.TERMS_GETUP)})")
    return matches[0]


def load_expert(path, name: str | None = None) -> Expert:
    """A tanh_normal policy from an artifact (.safetensors) or a brax PPO checkpoint / run directory."""
    path = Path(path)
    if path.suffix == ".safetensors":
        layers, mean, std, manifest = read_artifact(path)
        if manifest["output_rule"] != "tanh_normal":
            raise ValueError(f"{path}: output_rule {manifest['output_rule']!r}; an expert must be a PPO "
                             "tanh_normal policy (the DAgger loss compares tanh(loc))")
        return Expert(name or manifest["name"], tuple(layers), mean, std, manifest["activation"],
                      tuple((n, int(s)) for n, s in manifest["obs_terms"]), per_joint(manifest["action_scale"]))
    params = load_checkpoint(path)
    layers = brax_policy_layers(params[1])
    if layers[-1][0].shape[0] != 2 * obsdef.NUM_JOINTS:
        raise ValueError(f"{path}: policy outputs {layers[-1][0].shape[0]}, a tanh_normal T1 policy has "
                         f"{2 * obsdef.NUM_JOINTS}")
    mean, std = params[0].mean, params[0].std
    if isinstance(mean, dict):
        mean, std = mean[STUDENT_OBS_KEY], std[STUDENT_OBS_KEY]
    terms = _terms_for_size(layers[0][0].shape[1], path)
    # a checkpoint has no manifest: its task's action map, from the terms (getup or joystick config)
    scale = base.capped_action_scale(GETUP_ACTION_SCALE_RAD if terms == obsdef.TERMS_GETUP
                                     else base.base_config().action_scale,
                                     t1model.joint_ranges(t1model.load_model()))
    return Expert(name or path.name, tuple(layers), np.asarray(mean, np.float32), np.asarray(std, np.float32),
                  ACTIVATION, terms, per_joint(scale))


def per_joint(scale) -> np.ndarray:
    return np.broadcast_to(np.asarray(scale, np.float32), (obsdef.NUM_JOINTS,)).copy()


class TermAdapter:
    """Maps observations laid out as `source_terms` to `target_terms` (a jax/numpy function)."""

    FILLABLE = ("command", "phase")

    def __init__(self, source_terms: Sequence, target_terms: Sequence):
        obsdef.check_terms(target_terms)
        self.source_terms, self.target_terms = tuple(map(tuple, source_terms)), tuple(map(tuple, target_terms))
        self._plan = [(name, obsdef.term_slice(source_terms, name), int(size)) for name, size in target_terms]
        self.filled = [name for name, where, _ in self._plan if where is None]
        missing = [name for name in self.filled if name not in self.FILLABLE]
        if missing:
            raise ValueError(f"obs_terms: the env does not produce {missing} (env terms: "
                             f"{[n for n, _ in source_terms]}), and only {self.FILLABLE} can be filled in")
        self.identity = self.source_terms == self.target_terms

    def __call__(self, obs, xp=None):
        xp = xp or jnp
        if self.identity:
            return obs
        batch = obs.shape[:-1]
        parts = []
        for name, where, size in self._plan:
            if where is not None:
                parts.append(obs[..., where])
            elif name == "command":
                parts.append(xp.zeros(batch + (size,), obs.dtype))
            else:  # phase: frozen initial gait clock, [cos φL, cos φR, sin φL, sin φR]
                phi = obsdef.initial_gait_phase(np)
                frozen = np.concatenate([np.cos(phi), np.sin(phi)]).astype(np.float32)
                parts.append(xp.broadcast_to(xp.asarray(frozen, dtype=obs.dtype), batch + (size,)))
        return xp.concatenate(parts, axis=-1)
