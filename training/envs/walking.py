"""Walking on command, as the joystick env and the unified env's walking episodes share it: commands, pushes,
the feet's touchdown bookkeeping and the joystick reward terms (joystick_rewards.py) of Playground's T1.

A base of both envs over base.T1Env; it reads config fields both have (command_ranges, zero_command_prob,
command_resample_steps, push, gait, reward.tracking_sigma / max_foot_height_m, soft_joint_pos_limit_factor)
and info's command, push and feet entries, so the unified env's walking episodes draw commands and pushes from
exactly the joystick env's distributions and pay its terms.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp

from common import observation as obsdef
from training.envs import base
from training.envs import joystick_rewards as R

# Playground's pose-cost weights per joint (head, arms, waist, legs), joint order.
POSE_WEIGHTS = (1.0, 1.0, 0.1, 1.0, 1.0, 1.0, 0.1, 1.0, 1.0, 1.0, 1.0,
                0.01, 1.0, 1.0, 0.01, 1.0, 1.0, 0.01, 1.0, 1.0, 0.01, 1.0, 1.0)
HIP_JOINTS = ("Left_Hip_Roll", "Left_Hip_Yaw", "Right_Hip_Roll", "Right_Hip_Yaw")
KNEE_JOINTS = ("Left_Knee_Pitch", "Right_Knee_Pitch")


class Walking(base.T1Env):
    """Commands, pushes, feet bookkeeping and the joystick reward terms."""

    def _init_reward_constants(self) -> None:
        """What _reward_terms reads besides the state: soft joint limits, hip / knee indices, pose weights."""
        mj = self._mj_model
        lo, hi = self._q_min, self._q_max
        centre, half = (lo + hi) / 2, (hi - lo) / 2 * self._config.soft_joint_pos_limit_factor
        self._soft_lower, self._soft_upper = centre - half, centre + half
        self._hip_idx = jnp.array([mj.joint(n).qposadr[0] - 7 for n in HIP_JOINTS])
        self._knee_idx = jnp.array([mj.joint(n).qposadr[0] - 7 for n in KNEE_JOINTS])
        self._pose_weights = jnp.array(POSE_WEIGHTS)

    def sample_command(self, rng: jax.Array) -> jax.Array:
        r = self._config.command_ranges
        k = jax.random.split(rng, 4)
        cmd = jnp.stack([jax.random.uniform(k[0], minval=r.vx[0], maxval=r.vx[1]),
                         jax.random.uniform(k[1], minval=r.vy[0], maxval=r.vy[1]),
                         jax.random.uniform(k[2], minval=r.yaw_rate[0], maxval=r.yaw_rate[1])])
        return jnp.where(jax.random.bernoulli(k[3], self._config.zero_command_prob), jnp.zeros(3), cmd)

    def _push_interval_steps(self, rng):
        lo, hi = self._config.push.interval_range_s
        return jnp.round(jax.random.uniform(rng, minval=lo, maxval=hi) / self.dt).astype(jnp.int32)

    @staticmethod
    def initial_feet_info() -> dict:
        return {"feet_air_time": jnp.zeros(2), "last_contact": jnp.zeros(2, dtype=bool), "swing_peak": jnp.zeros(2)}

    def _feet_touchdown(self, data, info: dict):
        """(contact, first_contact) of the state after the step; advances info's air times and swing peaks
        (in place) as Playground's T1 does."""
        contact = self.foot_contacts(data)
        first_contact = (info["feet_air_time"] > 0.0) * (contact | info["last_contact"])
        info["feet_air_time"] = info["feet_air_time"] + self.dt
        info["swing_peak"] = jnp.maximum(info["swing_peak"], data.site_xpos[self._feet_sites][:, 2])
        return contact, first_contact

    @staticmethod
    def _feet_after_step(info: dict, contact) -> None:
        """Feet on the floor start a new swing (in place), after the reward read this step's."""
        info["feet_air_time"] = info["feet_air_time"] * ~contact
        info["last_contact"] = contact
        info["swing_peak"] = info["swing_peak"] * ~contact

    def _scaled_reward_terms(self, scales, data, action, info, first_contact, contact) -> dict[str, jax.Array]:
        return {k: v * scales[k] for k, v in self._reward_terms(data, action, info, first_contact, contact).items()}

    def _advance_clock_and_command(self, info: dict, action: jax.Array, k_cmd: jax.Array) -> None:
        """Tick bookkeeping (in place): the gait clock advances with the command in force during this step,
        then the command may be resampled; the next observation sees both (the runtime does the same)."""
        gcfg = self._config.gait
        info["phase"] = obsdef.advance_gait_phase(info["phase"], info["command"], gcfg.frequency_hz, self.dt,
                                                  gcfg.phase_freeze_command_norm, jnp)
        info["last_act"] = action
        info["command_step"] = info["command_step"] + 1
        resample = info["command_step"] >= self._config.command_resample_steps
        info["command"] = jnp.where(resample, self.sample_command(k_cmd), info["command"])
        info["command_step"] = jnp.where(resample, 0, info["command_step"])

    def _push_magnitude(self, rng):
        """Base speed change of one push [m/s]."""
        lo, hi = self._config.push.magnitude_range_mps
        return jax.random.uniform(rng, minval=lo, maxval=hi)

    def _apply_push(self, data, info, k_theta, k_mag):
        p = self._config.push
        theta = jax.random.uniform(k_theta, maxval=2 * jnp.pi)
        mag = self._push_magnitude(k_mag)
        due = jnp.mod(info["push_step"] + 1, info["push_interval_steps"]) == 0
        push = jnp.array([jnp.cos(theta), jnp.sin(theta)]) * mag * due * float(p.enable)
        info["push_step"] = info["push_step"] + 1
        info["push"] = push
        return data.replace(qvel=data.qvel.at[:2].add(push))

    def _reward_terms(self, data, action, info, first_contact, contact) -> dict[str, jax.Array]:
        cfg = self._config.reward
        cmd, q = info["command"], data.qpos[7:]
        linvel, gyro = self.sensor(data, "local_linvel"), self.sensor(data, "gyro")
        feet = data.site_xpos[self._feet_sites]
        xmat = data.site_xmat[self._imu_site]
        yaw = jnp.arctan2(xmat[1, 0], xmat[0, 0])
        return {
            "tracking_lin_vel": R.tracking_lin_vel(cmd, linvel, cfg.tracking_sigma),
            "tracking_ang_vel": R.tracking_ang_vel(cmd, gyro, cfg.tracking_sigma),
            "lin_vel_z": R.lin_vel_z(linvel),
            "ang_vel_xy": R.ang_vel_xy(gyro),
            "orientation": R.orientation(self.up_vector(data)),
            "torques": R.torques(data.actuator_force),
            "action_rate": R.action_rate(action, info["last_act"]),
            "energy": R.energy(data.qvel[6:], data.actuator_force),
            "feet_air_time": R.feet_air_time(info["feet_air_time"], first_contact, cmd),
            "feet_slip": R.feet_slip(data.qvel[0:3], contact),
            "feet_phase": R.feet_phase(feet[:, 2], info["phase"], cfg.max_foot_height_m, cmd,
                                       self._config.gait.phase_freeze_command_norm),
            "alive": R.alive(),
            "joint_deviation_knee": R.joint_deviation_knee(q, self._default_pose, self._knee_idx),
            "joint_deviation_hip": R.joint_deviation_hip(q, self._default_pose, self._hip_idx, cmd),
            "dof_pos_limits": R.dof_pos_limits(q, self._soft_lower, self._soft_upper),
            "pose": R.pose(q, self._default_pose, self._pose_weights),
            "feet_distance": R.feet_distance(feet[0], feet[1], yaw),
            "collision": R.collision(self.feet_touching(data)),
        }
