"""T1 base env over mujoco_playground's MjxEnv (impl='jax'), shared by joystick, getup and baseline.

What every task shares (ARCHITECTURE.md, Training):
* the ONE robot file, common/models/t1.xml, in a collision variant (training/envs/collision.py);
* PD at the motor, recomputed EVERY physics substep (n_substeps = ctrl_dt / sim_dt = 10) with the
  firmware's law and clamps (training/envs/motor.py), ONE gain set (the model's pd_kp / pd_kd), on the
  target the deployed runtime's supervisor would send at that 2 ms tick (rule R6: rate, torque, range;
  motor.supervised_target), its last value carried in info["runtime_target"];
* actions: q_des = default pose (home) + action_scale · action;
* the actor observation from common/observation.py (xp=jax.numpy) plus uniform noise U(−1, 1)·scale
  per term; a privileged critic observation;
* info["trunk_height"], info["waist_height"], info["up_z"] in every state.

The PD gains live in the MJX model as actuator_biasprm[:, 0] (kp) and [:, 1] (kd): the actuators are
plain motors (biastype none), so MuJoCo ignores these slots, and brax's domain-randomisation wrapper,
which swaps in a per-world mjx.Model, can then vary kp per world like Playground's T1 (randomize.py).
"""
from __future__ import annotations

import copy
from typing import Any, Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from ml_collections import config_dict
from mujoco import mjx
from mujoco_playground._src import mjx_env

from common import model as t1model
from common import observation as obsdef
from common.golden import DEFAULT_ACTION_SCALE
from messages import contract
from training.envs import collision, cpu_backend, motor, sagittal, wall_course

BACKENDS = ("mjx", "cpu")
FLOOR_GEOM = "floor"
KP_SLOT, KD_SLOT = 0, 1  # actuator_biasprm columns that carry the PD gains (see module docstring)
NUM_JOINTS = obsdef.NUM_JOINTS
# Jitted once here: called eagerly (a test, an evaluation's first state) MJX's forward runs op by op, minutes.
_forward = jax.jit(mjx.forward)
# Privileged extras appended to the clean actor observation (see privileged_base):
# local linvel 3, accelerometer 3, global angvel 3, trunk height, waist height, up_z, τ/τ_limit 23,
# foot contacts 2.
PRIVILEGED_BASE_SIZE = 3 + 3 + 3 + 3 + NUM_JOINTS + 2


def base_config() -> config_dict.ConfigDict:
    """Settings every task shares (tasks add their own). Times in s, action_scale in rad per unit."""
    return config_dict.create(
        ctrl_dt=contract.POLICY_PERIOD_S,   # the policy's step: every artifact's control_dt
        sim_dt=contract.LOOP_PERIOD_S,      # physics + PD substep: the runtime's loop tick
        episode_length=1000,
        action_scale=DEFAULT_ACTION_SCALE,   # rad per unit action: ±0.5 around home at |a| = 1
        action_space="full",   # the policy's action: "full" (23 joints) or "sagittal" (sagittal.py)
        collision="full_body",
        max_contacts=t1model.MJX_NCONMAX,
        max_geom_pairs=t1model.MJX_NCONMAX,
        obs_terms=[list(t) for t in obsdef.TERMS_UNION],
        gait=config_dict.create(frequency_hz=1.5, phase_freeze_command_norm=0.01),
        command_ranges=config_dict.create(vx=[-1.0, 1.0], vy=[-0.8, 0.8], yaw_rate=[-1.0, 1.0]),
        # U(−1, 1)·scale·level added per observation term (Playground T1 scales; 0 for exact terms).
        noise=config_dict.create(level=1.0, scales=config_dict.create(
            gyro=0.2, gravity=0.05, command=0.0, joint_pos=0.03, joint_vel=1.5, last_action=0.0, phase=0.0)),
        # the deployed runtime's target rule R6 (messages/contract.json supervisor.r6, the runtime's SafetyConfig
        # reads the same: 25 rad/s = 0.05 rad per 2 ms tick, 95 % of the joint range)
        supervisor=config_dict.create(max_target_speed_rps=contract.R6_MAX_TARGET_SPEED_RPS,
                                      joint_range_fraction=contract.R6_JOINT_RANGE_FRACTION),
        impl="jax",
        backend="mjx",   # physics engine: mjx (JAX, GPU) | cpu (MuJoCo C on all cores, cpu_backend.py)
        wall_course=wall_course.config(),   # the seed's low walls far down +x (wall_course.py; cpu backend)
    )


def contacts_between(data: mjx.Data, geom_a, geom_b) -> jax.Array:
    """True where geom_a (array of ids) touches geom_b (scalar id): a contact slot with penetration."""
    con = data._impl.contact
    g1, g2 = con.geom1[None, :], con.geom2[None, :]
    a = jnp.asarray(geom_a)[:, None]
    hit = ((g1 == a) & (g2 == geom_b)) | ((g2 == a) & (g1 == geom_b))
    return jnp.any(hit & (con.dist[None, :] < 0.0), axis=-1)


def capped_action_scale(scale_rad: float, joint_ranges: np.ndarray) -> float | np.ndarray:
    """Rad per unit action, per joint: the config's scale, but never more than the joint's whole range (the
    runtime's artifact rule); one number when that leaves every joint the same (the joystick's 0.5)."""
    scale = np.minimum(float(scale_rad), joint_ranges[:, 1] - joint_ranges[:, 0])
    return float(scale[0]) if np.all(scale == scale[0]) else scale


class T1Env(mjx_env.MjxEnv):
    """Shared model, PD, observation and bookkeeping. Subclasses implement reset/step and rewards."""

    def __init__(self, config: config_dict.ConfigDict, config_overrides: dict | None = None,
                 make_env: Callable | None = None) -> None:
        super().__init__(config, config_overrides)
        # the task registry's envs.make: the landing banks roll another task's env (starts/), which this
        # package's modules cannot import without an import circle; None: no bank can be built
        self._make_env = make_env
        cfg = self._config
        if cfg.impl != "jax":
            raise ValueError(f"impl {cfg.impl!r}: only 'jax' is supported (mujoco-mjx 3.17, no warp here)")
        ratio = cfg.ctrl_dt / cfg.sim_dt
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"ctrl_dt {cfg.ctrl_dt} s is not a whole multiple of sim_dt {cfg.sim_dt} s")
        obsdef.check_terms(cfg.obs_terms)
        backend = cfg.backend
        if backend not in BACKENDS:
            raise ValueError(f"backend {backend!r}: expected one of {BACKENDS}")
        if backend != "cpu" and self.has_wall_course():
            # MJX sizes its contact buffers per geom pair at compile time for the floor and the robot; the
            # walls' pairs are untested there
            raise ValueError("the wall course (wall_course.enable or a task's wall share > 0) needs backend 'cpu'")
        self._target_step, range_fraction = self._supervisor_settings(cfg)
        mj = self._compile(self._robot_spec().compile())
        self._mjx_model = mjx.put_model(mj, impl="jax")   # cpu: the randomisation's template only
        self._cpu = None
        if backend == "cpu":
            spec = self._robot_spec()
            cpu_backend.add_backend_elements(spec, collision.FOOT_GEOMS, FLOOR_GEOM)
            mj = self._compile(spec.compile())
            self._cpu = cpu_backend.CpuPhysics(mj, self.n_substeps, template=self._mjx_model,
                                               supervisor=(self._target_step, range_fraction))
        self._mj_model = mj

        self._default_pose_np = t1model.default_pose(mj)
        self._default_pose = jnp.asarray(self._default_pose_np)
        self._home_qpos = jnp.asarray(t1model.keyframe_qpos(mj, "home"))
        self._kneel_qpos = jnp.asarray(t1model.keyframe_qpos(mj, "kneel"))
        self._tau_limit = jnp.asarray(t1model.torque_limits(mj))
        ranges = t1model.joint_ranges(mj)
        self._q_min, self._q_max = jnp.asarray(ranges[:, 0]), jnp.asarray(ranges[:, 1])
        self._action_scale_np = capped_action_scale(cfg.action_scale, ranges)
        self._action_scale = jnp.asarray(self._action_scale_np, jnp.float32)
        self._action_size = sagittal.action_size(cfg.action_space)
        self._expansion = jnp.asarray(sagittal.expansion()) if cfg.action_space == "sagittal" else None
        self._d_safe = jnp.asarray(motor.D_SAFE_NMS)
        mid, half = 0.5 * (ranges[:, 0] + ranges[:, 1]), 0.5 * (ranges[:, 1] - ranges[:, 0]) * range_fraction
        self._range_lo, self._range_hi = jnp.asarray(mid - half), jnp.asarray(mid + half)

        self._trunk_id = mj.body("Trunk").id
        self._waist_id = mj.body("Waist").id
        self._imu_site = mj.site("imu").id
        self._feet_sites = np.array([mj.site("left_foot").id, mj.site("right_foot").id])
        self._floor_geom = mj.geom(FLOOR_GEOM).id
        self._foot_geoms = np.array([mj.geom(g).id for g in collision.FOOT_GEOMS])
        self._sensor = {n: (int(mj.sensor_adr[mj.sensor(n).id]), int(mj.sensor_dim[mj.sensor(n).id]))
                        for n in ("gyro", "accelerometer", "orientation", "local_linvel")}
        self._noise_scale = self._term_noise_vector()

    def _robot_spec(self) -> mujoco.MjSpec:
        """The robot in the config's collision variant (and the wall course where configured)."""
        cfg = self._config
        spec = collision.build_spec(cfg.collision, cfg.max_contacts, cfg.max_geom_pairs)
        if self.has_wall_course():
            wall_course.add_to_spec(spec, cfg.wall_course)
        return spec

    def has_wall_course(self) -> bool:
        """Whether this env's world holds the low-wall course: config wall_course.enable (tasks with a wall
        share override this to add it on their own)."""
        return bool(self._config.wall_course.enable)

    def _compile(self, model: mujoco.MjModel) -> mujoco.MjModel:
        """The env's copy of a compiled variant: its timestep and the ONE gain set in the PD slots."""
        mj = copy.copy(model)
        mj.opt.timestep = self._config.sim_dt
        self._kp, self._kd = t1model.pd_gains(mj)
        mj.actuator_biasprm[:, KP_SLOT] = self._kp
        mj.actuator_biasprm[:, KD_SLOT] = self._kd
        return mj

    @property
    def make_env(self) -> Callable | None:
        """The task registry's envs.make, for start banks that roll another task's env (None: no bank)."""
        return self._make_env

    @property
    def backend(self) -> str:
        return "cpu" if self._cpu is not None else "mjx"

    @property
    def cpu_physics(self) -> cpu_backend.CpuPhysics:
        if self._cpu is None:
            raise ValueError("cpu_physics: this env steps MJX (make it with backend='cpu')")
        return self._cpu

    def randomize_on_host(self, randomization_fn, seed: int) -> None:
        """CPU backend: apply brax's randomization_fn to every batch of simulations (instead of brax's
        MJX wrapper, which swaps mjx models the C physics never reads)."""
        if self._cpu is None:
            raise ValueError("randomize_on_host: only the cpu backend randomises on the host")
        self._cpu.set_randomization(randomization_fn, seed)

    # ------------------------------------------------------------------ MjxEnv accessors
    @property
    def xml_path(self) -> str:
        return str(t1model.MODEL_PATH)

    @property
    def action_size(self) -> int:
        return self._action_size

    def full_action(self, action: jax.Array) -> jax.Array:
        """The 23 joints' action of the policy's: what every step reads (observations, targets, artifacts)."""
        return action if self._expansion is None else self._expansion @ action

    @property
    def mj_model(self) -> mujoco.MjModel:
        return self._mj_model

    @property
    def mjx_model(self) -> mjx.Model:
        return self._mjx_model

    @property
    def obs_terms(self) -> list[tuple[str, int]]:
        return [(str(n), int(s)) for n, s in self._config.obs_terms]

    @property
    def config(self) -> config_dict.ConfigDict:
        return self._config

    def manifest_fields(self) -> dict[str, Any]:
        """Artifact manifest fields from this env's config (policies/ARTIFACT.md)."""
        cfg = self._config
        return {
            "obs_terms": [list(t) for t in self.obs_terms],
            "default_pose": [float(v) for v in self._default_pose_np],
            "action_scale": (self._action_scale_np if isinstance(self._action_scale_np, float)
                             else [float(v) for v in self._action_scale_np]),
            "kp": [float(v) for v in self._kp], "kd": [float(v) for v in self._kd],
            "control_dt": float(cfg.ctrl_dt),
            "gait_frequency": float(cfg.gait.frequency_hz),
            "phase_freeze_command_norm": float(cfg.gait.phase_freeze_command_norm),
            "command_ranges": {k: [float(x) for x in cfg.command_ranges[k]] for k in ("vx", "vy", "yaw_rate")},
        }

    # ------------------------------------------------------------------ physics
    def motor_targets(self, action: jax.Array) -> jax.Array:
        """q_des [rad] = default pose + action_scale · action (common/observation.action_to_targets)."""
        return obsdef.action_to_targets(self._default_pose, self._action_scale, action)

    def pd_torque(self, q_des: jax.Array, q: jax.Array, dq: jax.Array) -> jax.Array:
        """Firmware motor law with the (possibly randomised) gains of the current mjx model [N·m]."""
        m = self._mjx_model
        return motor.motor_torque(q_des, q, dq, m.actuator_biasprm[:, KP_SLOT], m.actuator_biasprm[:, KD_SLOT],
                                  self._tau_limit, self._q_min, self._q_max, self._d_safe)

    @staticmethod
    def _supervisor_settings(cfg) -> tuple[float, float]:
        """(max target step per physics substep [rad], joint-range fraction); runs configured before the
        supervisor was modelled get its defaults."""
        sup = cfg.supervisor if "supervisor" in cfg else base_config().supervisor
        return float(sup.max_target_speed_rps) * float(cfg.sim_dt), float(sup.joint_range_fraction)

    def substep_torque(self, q_des: jax.Array, last_target: jax.Array, q: jax.Array, dq: jax.Array):
        """One physics substep = one 2 ms runtime tick: (firmware torque [N·m], the supervisor's target [rad])."""
        m = self._mjx_model
        kp, kd = m.actuator_biasprm[:, KP_SLOT], m.actuator_biasprm[:, KD_SLOT]
        target = motor.supervised_target(q_des, last_target, q, dq, kp, kd, self._tau_limit, self._range_lo,
                                         self._range_hi, self._target_step)
        return self.pd_torque(target, q, dq), target

    def physics_step(self, data: mjx.Data, q_des: jax.Array, last_target: jax.Array):
        """One control step: n_substeps × (supervisor target and PD torque from the current q, dq → ctrl →
        mjx.step). Returns (data, the supervisor's last target [rad])."""
        if self._cpu is not None:
            return self._cpu.step(data, q_des, last_target)
        m = self._mjx_model

        def substep(carry, _):
            d, target = carry
            tau, target = self.substep_torque(q_des, target, d.qpos[7:], d.qvel[6:])
            return (mjx.step(m, d.replace(ctrl=tau)), target), None

        return jax.lax.scan(substep, (data, last_target), (), self.n_substeps)[0]

    @staticmethod
    def start_target(qpos: jax.Array) -> jax.Array:
        """info["runtime_target"] at a start: the start pose held (the runtime's last target is the pose it
        handed over from [rad])."""
        return qpos[7:7 + NUM_JOINTS].astype(jnp.float32)

    def make_data(self, qpos: jax.Array, qvel: jax.Array) -> mjx.Data:
        if self._cpu is not None:
            return self._cpu.make_data(qpos, qvel)
        data = mjx.make_data(self._mj_model, impl="jax")
        data = data.replace(qpos=qpos, qvel=qvel, ctrl=jnp.zeros(NUM_JOINTS))
        return _forward(self._mjx_model, data)

    # ------------------------------------------------------------------ readings
    def sensor(self, data: mjx.Data, name: str) -> jax.Array:
        adr, dim = self._sensor[name]
        return data.sensordata[adr:adr + dim]

    def trunk_height(self, data: mjx.Data) -> jax.Array:
        return data.xpos[self._trunk_id, 2]

    def waist_height(self, data: mjx.Data) -> jax.Array:
        return data.xpos[self._waist_id, 2]

    def up_vector(self, data: mjx.Data) -> jax.Array:
        """The Trunk (IMU) z axis in world coordinates; (0, 0, 1) when upright."""
        return data.site_xmat[self._imu_site][:, 2]

    def forward_z(self, data: mjx.Data) -> jax.Array:
        """World z of the Trunk (IMU) x axis: −1 lying face down, +1 on the back (common/events.forward_z_from_quat)."""
        return data.site_xmat[self._imu_site][2, 0]

    def foot_contacts(self, data: mjx.Data) -> jax.Array:
        """(left, right) foot box touching the floor."""
        if self._cpu is not None:
            return self._cpu.foot_contacts(data)
        return contacts_between(data, self._foot_geoms, self._floor_geom)

    def feet_touching(self, data: mjx.Data) -> jax.Array:
        """The two foot boxes touching each other (Playground's `collision` cost)."""
        if self._cpu is not None:
            return self._cpu.feet_touching(data)
        return contacts_between(data, self._foot_geoms[:1], self._foot_geoms[1])[0]

    def body_readings(self, data: mjx.Data) -> dict[str, jax.Array]:
        """The privileged scalars every state carries in info."""
        return {"trunk_height": self.trunk_height(data), "waist_height": self.waist_height(data),
                "up_z": self.up_vector(data)[2]}

    # ------------------------------------------------------------------ observations
    def observation_state(self, data: mjx.Data, command, last_action, gait_phase) -> obsdef.ObservationState:
        """IMU terms from the model's sensors, joint terms from qpos / qvel. As in C MuJoCo (HIL), the
        sensors after a step hold the readings of that substep's start (2 ms older than qpos)."""
        return obsdef.ObservationState(
            imu_quat=self.sensor(data, "orientation"), gyro=self.sensor(data, "gyro"), command=command,
            q=data.qpos[7:], dq=data.qvel[6:], default_pose=self._default_pose, last_action=last_action,
            gait_phase=gait_phase)

    def _term_noise_vector(self) -> jax.Array:
        scales = self._config.noise.scales
        parts = [np.full(size, float(scales[name]) if name in scales else 0.0) for name, size in self.obs_terms]
        return jnp.asarray(np.concatenate(parts))

    def actor_observation(self, state: obsdef.ObservationState, rng: jax.Array, level) -> tuple[jax.Array, jax.Array]:
        """(noisy, clean) actor observation: build_observation(terms) + U(−1, 1)·scale_term·level."""
        clean = obsdef.build_observation(self.obs_terms, state, jnp)
        noise = jax.random.uniform(rng, clean.shape, minval=-1.0, maxval=1.0) * self._noise_scale * level
        return clean + noise, clean

    def privileged_base(self, data: mjx.Data, clean_actor_obs: jax.Array) -> jax.Array:
        """Critic input shared by all tasks: clean actor obs + PRIVILEGED_BASE_SIZE extras."""
        r = self.body_readings(data)
        return jnp.concatenate([
            clean_actor_obs, self.sensor(data, "local_linvel"), self.sensor(data, "accelerometer"),
            data.cvel[self._trunk_id, :3],  # global angular velocity of the trunk [rad/s]
            jnp.stack([r["trunk_height"], r["waist_height"], r["up_z"]]),
            data.actuator_force / self._tau_limit, self.foot_contacts(data).astype(jnp.float32)])

    def invalid(self, data: mjx.Data) -> jax.Array:
        return jnp.isnan(data.qpos).any() | jnp.isnan(data.qvel).any()
