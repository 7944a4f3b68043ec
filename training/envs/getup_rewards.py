"""Getup reward terms, each a small pure function (tests compute them by hand on fixed states).

Reading of the seed's keyframe-curriculum reward (ARCHITECTURE.md gives the gate numbers, the bonuses,
the pose and energy formulas; the shapes of the height and orientation terms are this project's):
* height     r_h = exp(−|h − h*| / HEIGHT_SCALE_M): h = Trunk origin height [m], h* = the stage target's
             trunk height (kneel keyframe 0.405 m, home 0.666 m). Exponential of the absolute error, so a
             lying robot (h ≈ 0.1 m) still sees a gradient.
* orientation r_o = (1 + up_z) / 2 ∈ [0, 1]: up_z = z of the Trunk's up vector (1 upright, −1 inverted).
* pose       r_p = exp(−0.5·‖q − q_ref‖²), q_ref = the stage target's 23 joint angles [rad].
* gate       g = (h ≥ 0.4 m) ∧ (|h − h*| ≤ 5 mm) ∧ (up-vector error 1 − up_z < 0.01). 1 − up_z equals
             ½‖u − e_z‖² for a unit up vector u. The kneel keyframe's trunk is at 0.405 m, so the same
             0.4 m floor works for both targets.
* bonuses    g·1.83 (height bonus) + g·0.6·r_p (pose bonus: the pose counts extra once the torso is there).
* energy     e = Σ_i |dq_i · τ_i / τmax_i| [rad/s], weighted by −energy_weight (0 until the energy
             fine-tune).
reward per control step = w_h·r_h + w_o·r_o + w_p·r_p + bonuses − energy_weight·e  (then × ctrl_dt).
"""
from __future__ import annotations

import jax.numpy as jnp

HEIGHT_SCALE_M = 0.1          # e-folding height error of r_h [m]
GATE_MIN_HEIGHT_M = 0.4       # torso must be at least this high [m]
GATE_HEIGHT_TOL_M = 0.005     # ... and within this of the target [m]
GATE_UP_ERROR = 0.01          # 1 − up_z below this
HEIGHT_BONUS = 1.83
POSE_BONUS = 0.6


def height_reward(trunk_height, target_height, scale=HEIGHT_SCALE_M):
    return jnp.exp(-jnp.abs(trunk_height - target_height) / scale)


def orientation_reward(up_z):
    return 0.5 * (1.0 + up_z)


def up_error(up_z):
    """1 − up_z: 0 upright, 2 upside down (= ½‖u − e_z‖² for a unit up vector)."""
    return 1.0 - up_z


def pose_reward(q, q_ref):
    return jnp.exp(-0.5 * jnp.sum(jnp.square(q - q_ref), axis=-1))


def gate_height(trunk_height, target_height):
    return (trunk_height >= GATE_MIN_HEIGHT_M) & (jnp.abs(trunk_height - target_height) <= GATE_HEIGHT_TOL_M)


def gate_upright(up_z):
    return up_error(up_z) < GATE_UP_ERROR


def gate(trunk_height, target_height, up_z):
    return gate_height(trunk_height, target_height) & gate_upright(up_z)


def height_bonus(gate_ok):
    return HEIGHT_BONUS * gate_ok.astype(jnp.float32)


def pose_bonus(gate_ok, pose_r):
    return POSE_BONUS * gate_ok.astype(jnp.float32) * pose_r


def energy_cost(dq, tau, tau_limit):
    """Σ |dq·τ/τmax| [rad/s]: mechanical power normalised per motor by its torque limit."""
    return jnp.sum(jnp.abs(dq * tau / tau_limit), axis=-1)


def select_target(reached_kneel, stage_is_kneel, kneel_value, home_value):
    """Stage switch: stage 1 always targets kneel, stage 2 always home; the full task targets kneel until
    the kneel gate has been passed once in the episode (latched), then home. `stage_is_kneel` is
    True for stage 1; for stage 2 the env sets reached_kneel True at reset."""
    use_kneel = stage_is_kneel | ~reached_kneel
    return jnp.where(use_kneel, kneel_value, home_value)


def action_rate_cost(action, last_action):
    return jnp.sum(jnp.square(action - last_action), axis=-1)


def joint_velocity_cost(dq):
    return jnp.sum(jnp.square(dq), axis=-1)
