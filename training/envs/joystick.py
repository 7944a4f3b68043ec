"""Joystick locomotion expert: Playground T1's joystick recipe on this project's model.

Restated from mujoco_playground locomotion/t1/joystick.py (Apache-2.0, DeepMind). Differences, on
purpose: the motor is the firmware PD on torque actuators (base.py), action_scale 0.5 (the shared
artifact default, gains are stiffer than Playground's), the gait clock is common/observation.py's
(fixed frequency from the manifest, FROZEN while ‖command‖ < phase_freeze_command_norm instead of
Playground's reset to π; feet_phase then asks for both feet on the floor, as Playground's π does), the actor sees TERMS_UNION (no base linear velocity: the T1's IMU cannot
measure it), contacts are read from MJX contacts of the foot boxes (no contact sensors in the model),
and the collision variant is feet-only (collision.py). Ankle passive damping randomisation of
Playground is not restated (this model has no passive damping; see randomize.py).
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
from training.envs import joystick_rewards as R

# Playground's pose-cost weights per joint (head, arms, waist, legs), joint order.
POSE_WEIGHTS = (1.0, 1.0, 0.1, 1.0, 1.0, 1.0, 0.1, 1.0, 1.0, 1.0, 1.0,
                0.01, 1.0, 1.0, 0.01, 1.0, 1.0, 0.01, 1.0, 1.0, 0.01, 1.0, 1.0)
HIP_JOINTS = ("Left_Hip_Roll", "Left_Hip_Yaw", "Right_Hip_Roll", "Right_Hip_Yaw")
KNEE_JOINTS = ("Left_Knee_Pitch", "Right_Knee_Pitch")


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


class Joystick(base.T1Env):
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
            bank = handover.handover_bank(self._make_env, h.getup_policy, int(h.bank_starts), int(h.seed))
            self._handover = jax.tree.map(jnp.asarray, bank)

    def _init_reward_constants(self) -> None:
        """What _reward_terms reads besides the state: soft joint limits, hip / knee indices, pose weights
        (a method, so that the unified env's fine-tuning reward builds the same from its own config)."""
        mj = self._mj_model
        lo, hi = self._q_min, self._q_max
        centre, half = (lo + hi) / 2, (hi - lo) / 2 * self._config.soft_joint_pos_limit_factor
        self._soft_lower, self._soft_upper = centre - half, centre + half
        self._hip_idx = jnp.array([mj.joint(n).qposadr[0] - 7 for n in HIP_JOINTS])
        self._knee_idx = jnp.array([mj.joint(n).qposadr[0] - 7 for n in KNEE_JOINTS])
        self._pose_weights = jnp.array(POSE_WEIGHTS)

    # ------------------------------------------------------------------ commands
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
        k_use, k_idx, _ = jax.random.split(rng, 3)   # three keys: the stream the hand-over stage trained on
        bank = self._handover
        idx = jax.random.randint(k_idx, (), 0, bank.qpos.shape[0])
        hq, hv = place(bank.qpos[idx], bank.qvel[idx], qpos[0:2], yaw)
        h_act = obsdef.targets_to_action(self._default_pose, self._action_scale, bank.joint_targets[idx], jnp)
        use = jax.random.uniform(k_use) < self._config.handover.prob
        return jnp.where(use, hq, qpos), jnp.where(use, hv, qvel), jnp.where(use, h_act, last_act), command

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
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

    # ------------------------------------------------------------------ observation / reward
    def _observe(self, data, info, contact, rng) -> dict[str, jax.Array]:
        s = self.observation_state(data, info["command"], info["last_act"], info["phase"])
        noisy, clean = self.actor_observation(s, rng, self._config.noise.level)
        privileged = jnp.concatenate([self.privileged_base(data, clean), info["feet_air_time"],
                                      data.site_xpos[self._feet_sites].ravel()])
        return {"state": noisy, "privileged_state": privileged}

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
