"""The ONE definition of the policy observation, the gait clock, the MLP forward pass and the action →
joint-target map. The C++ runtime reproduces exactly these functions (golden-vector parity, 1e-5).

Array namespace: every function takes `xp` (default numpy) and uses only operations that numpy and
jax.numpy share, so the same code runs on numpy arrays (export, golden vectors, tests) and on jax arrays
under jit/vmap (training: pass `xp=jax.numpy`). Inputs may carry leading batch axes; the last axis is
the vector axis. No Python control flow depends on array values, so everything traces.

Conventions (SI units): quaternions (w, x, y, z), body → world; gyro in rad/s in the IMU (trunk) frame;
joint angles in rad, joint velocities in rad/s; gait phases in rad; command = (vx [m/s], vy [m/s],
yaw_rate [rad/s]).
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple, Sequence

import numpy as np

from messages import contract

NUM_JOINTS: int = contract.NUM_JOINTS  # 23, joint order = messages/contract.json

# Term layout as data: ordered (name, size). The manifest's `obs_terms` must be a list of these.
TERM_SIZES: dict[str, int] = {
    "gyro": 3,
    "gravity": 3,
    "command": 3,
    "joint_pos": NUM_JOINTS,
    "joint_vel": NUM_JOINTS,
    "last_action": NUM_JOINTS,
    "phase": 4,
}
TERMS_UNION: tuple[tuple[str, int], ...] = tuple(
    (n, TERM_SIZES[n]) for n in ("gyro", "gravity", "command", "joint_pos", "joint_vel", "last_action", "phase"))
# The seed's getup observation (thesis Table 4.2): 52 entries, no last action.
TERMS_GETUP: tuple[tuple[str, int], ...] = tuple(
    (n, TERM_SIZES[n]) for n in ("gyro", "gravity", "joint_pos", "joint_vel"))

# Gait clock: the two feet start half a cycle apart (left 0, right π) [rad].
GAIT_PHASE_OFFSETS_RAD: tuple[float, float] = (0.0, math.pi)
TWO_PI: float = 2.0 * math.pi

ACTIVATIONS: tuple[str, ...] = ("swish", "elu", "tanh", "relu")
OUTPUT_RULES: tuple[str, ...] = ("tanh_normal", "linear")

# World gravity direction (unit vector, z up).
_GRAVITY_WORLD = (0.0, 0.0, -1.0)


class ObservationState(NamedTuple):
    """What the observation is computed from (a NamedTuple so it is a jax pytree: vmap/jit friendly)."""
    imu_quat: Any      # (..., 4) trunk orientation (w, x, y, z), body → world; need not be exactly unit
    gyro: Any          # (..., 3) body angular velocity [rad/s]
    command: Any       # (..., 3) (vx [m/s], vy [m/s], yaw_rate [rad/s])
    q: Any             # (..., 23) joint angles [rad]
    dq: Any            # (..., 23) joint velocities [rad/s]
    default_pose: Any  # (..., 23) [rad]
    last_action: Any   # (..., 23) previous policy action (before scaling)
    gait_phase: Any    # (..., 2) (φL, φR) [rad]


# ---------------------------------------------------------------- terms (one function per term)
def gravity_in_imu_frame(imu_quat, xp=np):
    """R(q)^T · (0, 0, −1): the world gravity direction seen in the IMU frame.

    The quaternion is normalised first, because the bus delivers it in float32 and a drifting estimator
    need not keep it unit; the C++ side does the same. Upright → (0, 0, −1); upside down → (0, 0, 1).
    """
    quat = imu_quat / xp.sqrt(xp.sum(imu_quat * imu_quat, axis=-1, keepdims=True))
    w, x, y, z = quat[..., 0], quat[..., 1], quat[..., 2], quat[..., 3]
    # R^T·(0,0,g) = g · (third row of R); the third row of R for a unit quaternion is below.
    r20 = 2.0 * (x * z - w * y)
    r21 = 2.0 * (y * z + w * x)
    r22 = 1.0 - 2.0 * (x * x + y * y)
    g = _GRAVITY_WORLD[2]
    return xp.stack([g * r20, g * r21, g * r22], axis=-1)


def term_gyro(state: ObservationState, xp=np):
    return state.gyro


def term_gravity(state: ObservationState, xp=np):
    return gravity_in_imu_frame(state.imu_quat, xp)


def term_command(state: ObservationState, xp=np):
    return state.command


def term_joint_pos(state: ObservationState, xp=np):
    return state.q - state.default_pose


def term_joint_vel(state: ObservationState, xp=np):
    return state.dq


def term_last_action(state: ObservationState, xp=np):
    return state.last_action


def term_phase(state: ObservationState, xp=np):
    """[cos φL, cos φR, sin φL, sin φR] (cosines first, then sines)."""
    phi = state.gait_phase
    return xp.concatenate([xp.cos(phi), xp.sin(phi)], axis=-1)


TERM_FUNCTIONS = {
    "gyro": term_gyro,
    "gravity": term_gravity,
    "command": term_command,
    "joint_pos": term_joint_pos,
    "joint_vel": term_joint_vel,
    "last_action": term_last_action,
    "phase": term_phase,
}
assert set(TERM_FUNCTIONS) == set(TERM_SIZES), "every term needs a size and a function"


def check_terms(terms: Sequence[Sequence[Any]]) -> int:
    """Validate an ordered (name, size) list against the known terms; return the observation size."""
    total = 0
    seen = set()
    for entry in terms:
        if len(entry) != 2:
            raise ValueError(f"obs_terms: entry {entry!r} is not a [name, size] pair")
        name, size = entry
        if name not in TERM_SIZES:
            raise ValueError(f"obs_terms: unknown term {name!r} (known: {sorted(TERM_SIZES)})")
        if name in seen:
            raise ValueError(f"obs_terms: term {name!r} appears twice")
        if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size != TERM_SIZES[name]:
            raise ValueError(f"obs_terms: term {name!r} has size {size!r}, expected {TERM_SIZES[name]}")
        seen.add(name)
        total += int(size)
    return total


def observation_size(terms: Sequence[Sequence[Any]]) -> int:
    return check_terms(terms)


def term_slice(terms: Sequence[Sequence[Any]], name: str) -> slice | None:
    """Where term `name` sits in an observation laid out as `terms`; None when the layout lacks it."""
    check_terms(terms)
    start = 0
    for term, size in terms:
        if term == name:
            return slice(start, start + int(size))
        start += int(size)
    return None


def build_observation(terms: Sequence[Sequence[Any]], state: ObservationState, xp=np):
    """Concatenate the terms, in the given order, into one (..., N) vector (unnormalised)."""
    check_terms(terms)
    parts = [TERM_FUNCTIONS[name](state, xp) for name, _ in terms]
    return xp.concatenate(parts, axis=-1)


def normalize(obs, obs_mean, obs_std):
    """(x − mean) / std, the normaliser stored in the artifact (no clipping)."""
    return (obs - obs_mean) / obs_std


# ---------------------------------------------------------------- gait clock
def wrap_phase(phi, xp=np):
    """Wrap to [−π, π): φ − 2π·floor((φ + π) / 2π). Written with floor, not fmod, so C++ and Python
    agree for negative angles (C fmod keeps the dividend's sign)."""
    return phi - TWO_PI * xp.floor((phi + math.pi) / TWO_PI)


def initial_gait_phase(xp=np):
    """(φL, φR) at the start of an episode: the offsets (0, π), wrapped → (0, −π)."""
    return wrap_phase(xp.asarray(GAIT_PHASE_OFFSETS_RAD), xp)


def advance_gait_phase(gait_phase, command, gait_frequency_hz, control_dt_s, freeze_command_norm, xp=np):
    """One policy tick of the gait clock: φ ← wrap(φ + 2π·f·dt), unless ‖command‖ < freeze threshold,
    in which case φ is returned unchanged (frozen while standing still, as in training)."""
    command_norm = xp.sqrt(xp.sum(command * command, axis=-1, keepdims=True))
    advanced = wrap_phase(gait_phase + TWO_PI * gait_frequency_hz * control_dt_s, xp)
    return xp.where(command_norm < freeze_command_norm, gait_phase, advanced)


# ---------------------------------------------------------------- policy MLP
def activation_fn(name: str, x, xp=np):
    if name == "swish":  # x·sigmoid(x) (flax `swish` = `silu`, brax's default)
        return x / (1.0 + xp.exp(-x))
    if name == "elu":  # alpha = 1; expm1 only on the non-positive side so it cannot overflow
        return xp.where(x > 0, x, xp.expm1(xp.minimum(x, 0.0)))
    if name == "tanh":
        return xp.tanh(x)
    if name == "relu":
        return xp.maximum(x, 0.0)
    raise ValueError(f"activation: unknown {name!r} (known: {ACTIVATIONS})")


def mlp_forward(layers: Sequence[tuple[Any, Any]], obs_normalized, activation: str, output_rule: str,
                action_size: int = NUM_JOINTS, xp=np):
    """The policy: layers = [(W (out, in), b (out,)), ...]; hidden layers use `activation`, the last is
    linear; then the output rule: `tanh_normal` → tanh(first `action_size` outputs) (brax's deterministic
    tanh-normal action; the second half is the scale and is ignored), `linear` → the output as is."""
    if output_rule not in OUTPUT_RULES:
        raise ValueError(f"output_rule: unknown {output_rule!r} (known: {OUTPUT_RULES})")
    h = obs_normalized
    for i, (w, b) in enumerate(layers):
        h = h @ xp.asarray(w).T + xp.asarray(b)
        if i < len(layers) - 1:
            h = activation_fn(activation, h, xp)
    if output_rule == "tanh_normal":
        return xp.tanh(h[..., :action_size])
    return h


def policy_forward(layers, obs, obs_mean, obs_std, activation: str, output_rule: str, xp=np):
    """The one policy runner in Python (golden vectors, experts, evaluations): raw observation → normalised →
    MLP → output rule."""
    return mlp_forward(layers, normalize(obs, obs_mean, obs_std), activation, output_rule, xp=xp)


def action_to_targets(default_pose, action_scale, action):
    """Joint position targets [rad] = default_pose + action_scale · action (scale: scalar or per joint)."""
    return default_pose + action_scale * action


def targets_to_action(default_pose, action_scale, q_target, xp=np):
    """The inverse map, clipped to the action range: joint targets [rad] as a policy with this pose and
    scale would have commanded them (how one policy reads the targets another applied)."""
    return xp.clip((q_target - default_pose) / action_scale, -1.0, 1.0)


def policy_step(terms, state: ObservationState, layers, obs_mean, obs_std, activation, output_rule,
                action_scale, xp=np):
    """observation → normalised → action → targets, the whole per-tick computation. Returns a dict."""
    obs = build_observation(terms, state, xp)
    action = policy_forward(layers, obs, obs_mean, obs_std, activation, output_rule, xp=xp)
    return {"obs": obs, "obs_normalized": normalize(obs, obs_mean, obs_std), "action": action,
            "q_target": action_to_targets(state.default_pose, action_scale, action)}
