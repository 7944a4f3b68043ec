"""The planner's cost terms, per rollout and control step, as small named functions over (S, …) arrays.

From the seed's stage-1 reward (§4.7: height and orientation toward the kneel, pose toward the kneel keyframe,
energy) plus §4.8's gate, reshaped for a sampler (ours, not the seed's reward): the height is two-sided
(a one-sided term let the probe overshoot into a crouch), the pose is a weighted square (the seed's
exp(−½‖Δq‖²) is flat far from the kneel, where a sampler needs a slope) and, near the kneel, the root's twist
is charged so the plan balances rather than sways."""
from __future__ import annotations

import numpy as np

from common import events


def height_cost(h: np.ndarray, h_target: float) -> np.ndarray:
    return np.square(h - h_target)


def orientation_cost(up_z: np.ndarray, up_z_target: float) -> np.ndarray:
    """|u_z − its target|: at the kneel 1 − u_z ≈ tilt²/2, a slope down to the gate's 0.57° (a square of it
    is flat there)."""
    return np.abs(up_z - up_z_target)


def pose_cost(q: np.ndarray, q_target: np.ndarray, joint_weight: np.ndarray) -> np.ndarray:
    return np.sum(joint_weight * np.square(q - q_target), axis=-1)


def energy_cost(tau: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Σ|τ·q̇| [W]: the seed's energy term without its per-joint torque normalisation (a planner's cost)."""
    return np.sum(np.abs(tau * dq), axis=-1)


def gate(h: np.ndarray, up_z: np.ndarray) -> np.ndarray:
    """§4.8's gate, as common/events.py counts it."""
    return events.kneel_gate_mask(h, up_z)


def step_cost(r: dict, target: dict, w, near: np.ndarray) -> np.ndarray:
    """One control step's cost of every rollout. r: readings (h, h_waist, up_z, q, dq, tau, root_vel);
    target: the keyframe's (h, h_waist, up_z, q, joint_weight, upright_weight); w: the config's weights;
    near: (S,) bool."""
    return (w.trunk_height * height_cost(r["h"], target["h"])
            + w.waist_height * height_cost(r["h_waist"], target["h_waist"])
            + target["upright_weight"] * orientation_cost(r["up_z"], target["up_z"])
            + pose_cost(r["q"], target["q"], target["joint_weight"])
            + w.energy * energy_cost(r["tau"], r["dq"])
            + w.root_velocity * near * np.sum(np.square(r["root_vel"]), axis=-1)
            - w.gate * gate(r["h"], r["up_z"]))
