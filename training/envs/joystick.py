"""Joystick locomotion expert: Playground T1's joystick recipe on this project's model.

Restated from mujoco_playground locomotion/t1/joystick.py (Apache-2.0, DeepMind). Differences, on
purpose: the motor is the firmware PD on torque actuators (base.py), action_scale 0.5 (the shared
artifact default, gains are stiffer than Playground's), the gait clock is common/observation.py's
(fixed frequency from the manifest, FROZEN while ‖command‖ < phase_freeze_command_norm instead of
Playground's reset to π; feet_phase then asks for both feet on the floor, as Playground's π does), the actor
sees TERMS_UNION (no base linear velocity: the T1's IMU cannot measure it), contacts are read from MJX contacts
of the foot boxes (no contact sensors in the model), and the collision variant is feet-only (collision.py).
Ankle passive damping randomisation of Playground is not restated (this model has no passive damping; see
randomize.py). Commands, pushes, feet bookkeeping and the reward terms: walking.py (the unified env walks with
them too).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict
from mujoco_playground._src import mjx_env

from common import observation as obsdef
from training.envs import base, starts
from training.envs.starts import handover
from training.envs.starts.bank import place
from training.envs.walking import Walking


def default_config() -> config_dict.ConfigDict:
    cfg = base.base_config()
    cfg.collision = "feet_only"
    cfg.episode_length = 1000
    cfg.soft_joint_pos_limit_factor = 0.95
    cfg.command_resample_steps = 500
    cfg.zero_command_prob = 0.1
    cfg.reset = config_dict.create(xy_range_m=0.5, yaw_range_rad=3.14, joint_scale=[0.5, 1.5],
                                   root_vel_range=0.5)
    cfg.push = config_dict.create(enable=True, interval_range_s=[5.0, 10.0], magnitude_range_mps=[0.1, 1.0])
    starts.add_config_groups(cfg, "joystick")   # hand-over starts (starts/handover.py; ours)
    cfg.reward = config_dict.create(
        scales=config_dict.create(
            tracking_lin_vel=1.0, tracking_ang_vel=0.5, lin_vel_z=0.0, ang_vel_xy=-0.15, orientation=-1.0,
            torques=0.0, action_rate=0.0, energy=0.0, feet_air_time=2.0, feet_slip=-0.25, feet_phase=1.0,
            alive=0.25, joint_deviation_knee=-0.1, joint_deviation_hip=-0.1, dof_pos_limits=-1.0,
            pose=-1.0, feet_distance=-1.0, collision=-1.0),
        tracking_sigma=0.25,
        max_foot_height_m=0.12)
    return cfg


class Joystick(Walking):
    """Track (vx, vy, yaw_rate) commands; actor obs TERMS_UNION (82), critic privileged."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)
        self._init_reward_constants()
        self._handover = None
        h = self._config.handover
        if not 0.0 <= h.prob <= 1.0:
            raise ValueError(f"handover.prob must be in [0, 1], got {h.prob}")
        if h.prob > 0:
            if not h.getup_policy:
                raise ValueError("handover.prob > 0 needs handover.getup_policy (a getup artifact or checkpoint)")
            bank = handover.handover_bank(self._make_env, h)
            self._handover = jax.tree.map(jnp.asarray, bank)

    # ------------------------------------------------------------------ reset / step
    def reset(self, rng: jax.Array) -> mjx_env.State:
        cfg = self._config.reset
        rng, k_xy, k_yaw, k_q, k_v, k_cmd, k_push, k_obs = jax.random.split(rng, 8)
        qpos = self._home_qpos
        qpos = qpos.at[0:2].add(jax.random.uniform(k_xy, (2,), minval=-cfg.xy_range_m, maxval=cfg.xy_range_m))
        yaw = jax.random.uniform(k_yaw, minval=-cfg.yaw_range_rad, maxval=cfg.yaw_range_rad)
        qpos = qpos.at[3:7].set(jnp.array([jnp.cos(yaw / 2), 0.0, 0.0, jnp.sin(yaw / 2)]))
        qpos = qpos.at[7:].multiply(jax.random.uniform(k_q, (base.NUM_JOINTS,), minval=cfg.joint_scale[0],
                                                       maxval=cfg.joint_scale[1]))
        qvel = jnp.zeros(self._mj_model.nv).at[0:6].set(
            jax.random.uniform(k_v, (6,), minval=-cfg.root_vel_range, maxval=cfg.root_vel_range))
        last_act = jnp.zeros(base.NUM_JOINTS)
        command = self.sample_command(k_cmd)
        if self._handover is not None:
            rng, k_hand = jax.random.split(rng)
            qpos, qvel, last_act, command = self._maybe_handover_start(k_hand, qpos, qvel, last_act, yaw, command)
        data = self.make_data(qpos, qvel)

        info = {
            "rng": rng,
            "command": command,
            "command_step": jnp.array(0, jnp.int32),
            "last_act": last_act,
            "motor_targets": self._default_pose,
            "runtime_target": self.start_target(qpos),
            **self.initial_feet_info(),
            "phase": obsdef.initial_gait_phase(jnp).astype(jnp.float32),
            "push": jnp.zeros(2),
            "push_step": jnp.array(0, jnp.int32),
            "push_interval_steps": self._push_interval_steps(k_push),
            **self.body_readings(data),
        }
        contact = self.foot_contacts(data)
        obs = self._observe(data, info, contact, k_obs)
        metrics = {f"reward/{k}": jnp.zeros(()) for k in self._config.reward.scales.keys()}
        metrics["swing_peak"] = jnp.zeros(())
        return mjx_env.State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def _maybe_handover_start(self, rng, qpos, qvel, last_act, yaw, command):
        """With probability handover.prob, a hand-over state instead of the standing start, at the standing
        start's place and heading; its last action = the getup expert's last targets in this env's map."""
        k_use, k_idx = jax.random.split(rng)
        bank = self._handover
        idx = jax.random.randint(k_idx, (), 0, bank.qpos.shape[0])
        hq, hv = place(bank.qpos[idx], bank.qvel[idx], qpos[0:2], yaw)
        h_act = obsdef.targets_to_action(self._default_pose, self._action_scale, bank.joint_targets[idx], jnp)
        use = jax.random.uniform(k_use) < self._config.handover.prob
        return jnp.where(use, hq, qpos), jnp.where(use, hv, qvel), jnp.where(use, h_act, last_act), command

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
        action = self.full_action(action)
        info = dict(state.info)
        info["rng"], k_theta, k_mag, k_cmd, k_obs = jax.random.split(info["rng"], 5)
        data = self._apply_push(state.data, info, k_theta, k_mag)
        q_des = self.motor_targets(action)
        data, info["runtime_target"] = self.physics_step(data, q_des, info["runtime_target"])
        info["motor_targets"] = q_des

        contact, first_contact = self._feet_touchdown(data, info)
        info.update(self.body_readings(data))

        done = (info["up_z"] < 0.0) | self.invalid(data)
        scaled = self._scaled_reward_terms(self._config.reward.scales, data, action, info, first_contact, contact)
        reward = jnp.clip(sum(scaled.values()) * self.dt, 0.0, 10000.0)

        self._advance_clock_and_command(info, action, k_cmd)
        self._feet_after_step(info, contact)

        obs = self._observe(data, info, contact, k_obs)
        metrics = dict(state.metrics)
        for k, v in scaled.items():
            metrics[f"reward/{k}"] = v
        metrics["swing_peak"] = jnp.mean(info["swing_peak"])
        return state.replace(data=data, obs=obs, reward=reward, done=done.astype(reward.dtype),
                             metrics=metrics, info=info)

    # ------------------------------------------------------------------ observation / reward
    def _observe(self, data, info, contact, rng) -> dict[str, jax.Array]:
        s = self.observation_state(data, info["command"], info["last_act"], info["phase"])
        noisy, clean = self.actor_observation(s, rng, self._config.noise.level)
        privileged = jnp.concatenate([self.privileged_base(data, clean), info["feet_air_time"],
                                      data.site_xpos[self._feet_sites].ravel()])
        return {"state": noisy, "privileged_state": privileged}
