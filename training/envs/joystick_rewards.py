"""Joystick reward terms: Playground T1's recipe restated as small pure functions (Apache-2.0 recipe by
DeepMind, mujoco_playground locomotion/t1/joystick.py). Each returns the UNSCALED term; the env
multiplies by config.reward.scales[name] and by ctrl_dt. Units: m, rad, s."""
from __future__ import annotations

import jax.numpy as jnp
from mujoco_playground._src import gait

AIR_TIME_MIN_S, AIR_TIME_MAX_S = 0.2, 0.5   # feet_air_time window (Playground's thresholds)
MOVING_COMMAND_NORM = 0.1                   # below: "standing" command (air time / hip deviation off)
FEET_PHASE_SIGMA_M2 = 0.01                  # exp(−Σ(z − z_ref)² / σ) width [m²]
FEET_MIN_DISTANCE_M, FEET_DISTANCE_CAP_M = 0.2, 0.1


def tracking_lin_vel(command, local_linvel, sigma):
    return jnp.exp(-jnp.sum(jnp.square(command[:2] - local_linvel[:2])) / sigma)


def tracking_ang_vel(command, gyro, sigma):
    return jnp.exp(-jnp.square(command[2] - gyro[2]) / sigma)


def ang_vel_xy(gyro):
    return jnp.sum(jnp.square(gyro[:2]))


def orientation(up_vector):
    """Tilt cost: squared x, y components of the trunk's up vector in the world frame."""
    return jnp.sum(jnp.square(up_vector[:2]))


def feet_air_time(air_time_s, first_contact, command):
    """Reward air time in [0.2, 0.5] s at each touchdown, only while a motion is commanded."""
    t = jnp.clip((air_time_s - AIR_TIME_MIN_S) * first_contact, None, AIR_TIME_MAX_S - AIR_TIME_MIN_S)
    return jnp.sum(t) * (jnp.linalg.norm(command) > MOVING_COMMAND_NORM)


def feet_slip(trunk_global_linvel, contact):
    """Playground's T1 reads the TRUNK's planar speed here (not the feet's), times the contact flags."""
    return jnp.sum(jnp.linalg.norm(trunk_global_linvel[:2]) * contact)


def feet_phase(foot_z, phase, max_foot_height, command, clock_freeze_command_norm):
    """Swing-height tracking of the gait clock's Bezier reference; both feet on the floor while the command
    is below the clock's freeze threshold. Why: our clock freezes there wherever it stopped (the
    observation contract), where Playground resets it to π, i.e. both feet in stance. Tracking a frozen
    mid-swing reference teaches the policy to stand on one leg at zero command, and to fall after stopping
    from a walk (training/LESSONS.md)."""
    standing = jnp.linalg.norm(command) < clock_freeze_command_norm
    rz = jnp.where(standing, 0.0, gait.get_rz(phase, swing_height=max_foot_height))
    return jnp.exp(-jnp.sum(jnp.square(foot_z - rz)) / FEET_PHASE_SIGMA_M2)


def alive():
    return jnp.ones(())  # strongly typed: a weak-typed metric would make jit retrace every step


def joint_deviation_hip(q, default_pose, hip_indices, command):
    """|hip roll/yaw − default|, only while a lateral velocity is commanded (Playground)."""
    cost = jnp.sum(jnp.abs(q[hip_indices] - default_pose[hip_indices]))
    return cost * (jnp.abs(command[1]) > MOVING_COMMAND_NORM)


def joint_deviation_knee(q, default_pose, knee_indices):
    return jnp.sum(jnp.abs(q[knee_indices] - default_pose[knee_indices]))


def dof_pos_limits(q, soft_lower, soft_upper):
    return jnp.sum(-jnp.clip(q - soft_lower, None, 0.0) + jnp.clip(q - soft_upper, 0.0, None))


def pose(q, default_pose, weights):
    return jnp.sum(jnp.square(q - default_pose) * weights)


def feet_distance(left_foot_pos, right_foot_pos, trunk_yaw):
    """Penalise feet closer than 0.2 m laterally (in the heading frame), capped at 0.1."""
    lateral = jnp.abs(jnp.cos(trunk_yaw) * (left_foot_pos[1] - right_foot_pos[1])
                      - jnp.sin(trunk_yaw) * (left_foot_pos[0] - right_foot_pos[0]))
    return jnp.clip(FEET_MIN_DISTANCE_M - lateral, 0.0, FEET_DISTANCE_CAP_M)


def collision(feet_touching):
    return feet_touching.astype(jnp.float32)


def lin_vel_z(local_linvel):
    return jnp.square(local_linvel[2])


def action_rate(action, last_action):
    return jnp.sum(jnp.square(action - last_action))


def torques(tau):
    return jnp.sum(jnp.abs(tau))


def energy(dq, tau):
    return jnp.sum(jnp.abs(dq * tau))
