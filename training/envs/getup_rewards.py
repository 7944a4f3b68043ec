"""The getup tasks' reward terms (thesis §4.7–4.8), each a small pure function (tests compute them by hand);
a task's config weights them by `reward.scales` (envs/getup_base.py sums them × ctrl_dt).

Height & orientation (§4.7), per body part p ∈ {torso, waist} with desired height h_p^des [m]:
    r_p      = 1 − clip((h_p^des − min(h_p, h_p^des)) / h_p^des, 0, 1)
    r_height = r_torso + r_waist ∈ [0, 2]
    r_ori    = (0.25·u_z + 0.5)²                (u_z: z of the torso's up vector, 1 upright, −1 inverted)
    reward   = 2·r_ori·(r_height + 1) / 3
Pose (§4.7): exp(−0.5·‖q − q_ref‖²) over the 23 joint angles [rad].
Turn (ours, the roll onto the front): (1 − f_z) / 2, f_z the world z of the torso's forward axis.
Energy cost (§4.7): Σ_i |v_i · τ_i / τmax_i| [rad/s], used only in the energy fine-tune.
Gate (§4.8): common/events.kneel_gate, the evaluations' own definition (trunk within 0.005 m of the contract's
kneel gate height or above, tilt below 0.573°). Standing targets: the contract's standing_target_trunk_m / _waist_m.
Gated terms (§4.8):
    Height Reward = (1 − gate)·HO(kneel targets) + gate·(1.83 + HO(standing targets))
    Pose Reward   = (1 − gate)·pose(q, q_kneel)  + gate·(0.6 + 100·pose(q, q_init))   (q_init: standing pose)
Failed rise (ours, not the seed's): the rise tracker counts a getup attempt that fails by common/events.py's
definitions (the trunk rose ATTEMPT_RISE_M from its low while down, then dropped ATTEMPT_RISE_M below the
attempt's peak before a stand-up held STAND_HOLD_S): the getup tasks' metric failed_rises, and the unified env's
reward.getup.failed_rise_cost.
"""
from __future__ import annotations

import jax.numpy as jnp

from common import events

GATE_UP_ERROR = events.KNEEL_GATE_UP_ERROR            # ‖u − e_z‖ below this
STANDUP_HEIGHT_BONUS = 1.83    # gate·(1.83 + …) in the Height Reward
STANDUP_POSE_BONUS = 0.6       # gate·(0.6 + …) in the Pose Reward
STANDUP_POSE_WEIGHT = 100.0    # gate·(… + 100·pose(q, q_init))
HO_MAX = 1.125   # height_orientation_reward upright (r_ori 0.5625) at both targets: 2·0.5625·(2 + 1)/3


def part_height_reward(h, h_des):
    """1 − clip((h_des − min(h, h_des)) / h_des, 0, 1): 1 at or above the target, 0 on the floor."""
    return 1.0 - jnp.clip((h_des - jnp.minimum(h, h_des)) / h_des, 0.0, 1.0)


def orientation_reward(up_z):
    """(0.25·u_z + 0.5)²: 0.5625 upright, 0.25 on its side, 0.0625 upside down."""
    return jnp.square(0.25 * up_z + 0.5)


def height_orientation_reward(h_torso, h_waist, up_z, torso_des, waist_des):
    """2·r_ori·(r_torso + r_waist + 1) / 3 ∈ [0.0417, 1.125]."""
    r_height = part_height_reward(h_torso, torso_des) + part_height_reward(h_waist, waist_des)
    return 2.0 * orientation_reward(up_z) * (r_height + 1.0) / 3.0


def pose_reward(q, q_ref):
    return jnp.exp(-0.5 * jnp.sum(jnp.square(q - q_ref), axis=-1))


def turn_reward(forward_z):
    """(1 − f_z) / 2 of the trunk's forward axis' world z: 0 on the back, 0.5 on its side, 1 face down (the roll)."""
    return 0.5 * (1.0 - forward_z)


def rise_track_start(h_torso):
    """The failed-rise tracker's state at an episode start, events.py's (down, in attempt, low, high [m],
    ticks standing): down from the start when the trunk is below the fallen height."""
    h = jnp.asarray(h_torso, jnp.float32)
    return {"down": h < events.FALLEN_TRUNK_HEIGHT_M, "rising": jnp.zeros((), bool), "low": h, "high": h,
            "stand_ticks": jnp.zeros((), jnp.int32)}


def rise_track_step(track, h_torso, standing, hold_ticks):
    """(next track, failed) after one control tick with trunk height h_torso [m] and `standing` (events'
    standing condition); a stand-up ends the down phase once it held hold_ticks ticks. While standing no
    attempt can fail (standing is above any peak − ATTEMPT_RISE_M), so ending it after the hold counts the
    same failures as events.getup_events' stand-up at the run's first sample."""
    rise_m = events.ATTEMPT_RISE_M
    down, rising = track["down"], track["rising"]
    stand_ticks = jnp.where(standing, track["stand_ticks"] + 1, 0)
    high = jnp.where(rising, jnp.maximum(track["high"], h_torso), track["high"])
    failed = down & rising & (h_torso <= high - rise_m)
    low = jnp.where(rising, jnp.where(failed, h_torso, track["low"]), jnp.minimum(track["low"], h_torso))
    start = down & ~rising & (h_torso >= low + rise_m)
    high = jnp.where(start, h_torso, high)
    enter = ~down & (h_torso < events.FALLEN_TRUNK_HEIGHT_M)
    stood = down & (stand_ticks >= hold_ticks)
    track = {"down": (down | enter) & ~stood, "rising": (rising | start) & ~failed & ~stood,
             "low": jnp.where(enter, h_torso, low), "high": high, "stand_ticks": stand_ticks}
    return track, failed


def up_error(up):
    """‖u − e_z‖ of the torso's up vector u (world frame, 3-vector)."""
    return jnp.linalg.norm(up - jnp.array([0.0, 0.0, 1.0]), axis=-1)


def gate(h_torso, up_z):
    """§4.8's gate at this step (common/events.kneel_gate under jax)."""
    return events.kneel_gate(h_torso, up_z, jnp)


def at_gate_height(h_torso):
    """The gate's height condition alone: 0.4 − min(h_torso, 0.4) < 0.005."""
    return events.at_kneel_gate_height(h_torso, jnp)


def latched_gate(gate_now, was_on, h_torso):
    """The gate held since it was last met, until the trunk is down (below the fallen height)."""
    return (gate_now | was_on) & (h_torso >= events.FALLEN_TRUNK_HEIGHT_M)


def upright_at_gate_height(h_torso, up):
    """exp(−‖u − e_z‖ / the gate's 0.01) while the trunk is at the gate's height: a slope over the last degrees
    to the gate (0.37 at its edge, 0.03 at 2°), where the orientation reward (a square of up_z) is flat (ours)."""
    return at_gate_height(h_torso).astype(jnp.float32) * jnp.exp(-up_error(up) / GATE_UP_ERROR)


def gated_height_reward(gate_ok, ho_kneel, ho_standing):
    g = gate_ok.astype(jnp.float32)
    return (1.0 - g) * ho_kneel + g * (STANDUP_HEIGHT_BONUS + ho_standing)


def gated_pose_reward(gate_ok, pose_kneel, pose_standing):
    g = gate_ok.astype(jnp.float32)
    return (1.0 - g) * pose_kneel + g * (STANDUP_POSE_BONUS + STANDUP_POSE_WEIGHT * pose_standing)


def gated_reward_max(height_scale: float = 1.0, pose_scale: float = 1.0) -> float:
    """The most height_scale · Height + pose_scale · Pose Reward pays per step (scales >= 0; gate on, HO at its
    1.125 ceiling, pose 1)."""
    return (height_scale * STANDUP_HEIGHT_BONUS + height_scale * HO_MAX + pose_scale * STANDUP_POSE_BONUS
            + pose_scale * STANDUP_POSE_WEIGHT)


def energy_cost(dq, tau, tau_limit):
    """Σ |dq·τ/τmax| [rad/s]: mechanical power normalised per motor by its torque limit."""
    return jnp.sum(jnp.abs(dq * tau / tau_limit), axis=-1)
