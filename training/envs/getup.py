"""Getup expert: the seed's keyframe curriculum (thesis §4.5–4.8) on the full-body-collision model.

Stages (config.stage), rewards from getup_rewards.py (formulas there):
* "stage1" fallen → kneel: Height = HO(kneel targets), Pose = pose(q, q_kneel); ours, off by default:
  config.stage1_gate_reward per step while the gate holds, config.stage1_upright_reward × a slope toward its
  tilt at its height.
* "stage2" kneel → stand: Height = HO(torso 0.67, waist 0.55), Pose = pose(q, q_init). The gate's 1.83 / 0.6
  bonuses and 100· weight belong to the full task (§4.8): without a gate they pay standing-like joint angles in
  any posture (LESSONS, `getup_stage2`).
* "full" (from stage 2, §4.5): fallen / kneeling / standing starts (config.start_probs), Height and Pose gated.
  Ours: the gate latches (config.gate_latches) until the trunk is down (0.35 m), because a standing robot keeps
  the per-step gate's 0.573° only now and then (LESSONS, `getup_full*`).
reward per control step = (Height + Pose − energy_weight·energy) × ctrl_dt; metric failed_rises counts the
attempts that fail by common/events.py's definition. Fine-tunes: energy_weight (§4.7), obs_noise_scale
(U(−1, 1)·scale on every observation entry, §4.6).
Actor obs = Table 4.2, TERMS_GETUP (52). "success" = standing by common/events.py (trunk ≥ 0.6 m, up_z ≥ 0.9).
Episodes end early only on non-finite physics and, in stage 2 alone (ours), when the robot leaves the kneel
downward (config.stage2_fall_trunk_height_m, stage2_fall_up_z): stage 2's Pose pays straight legs in any
posture, and without the end PPO learned to lie or lean back with straight legs (LESSONS, `getup_stage2`);
and, with config.stage1_drop_below_m > 0 (ours, off by default), in stage 1 once the trunk, having reached the
gate's height, drops that far below it (DeepMimic's early termination: a kneel let sag ends the episode).
Ours, off by default: a sagittal, mirrored action space (config.action_space, envs/sagittal.py: the env expands
the policy's pitch-joint action to the 23 joints before anything reads it); stage 2's reverse curriculum
(starts/kneeling_path.py) and a share of the fallen starts from the start banks (starts/).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from ml_collections import config_dict
from mujoco_playground._src import mjx_env

from common import observation as obsdef
from training.envs import base
from training.envs import getup_rewards as G
from training.envs import sagittal, starts
from training.envs.starts import kneeling_path
from common.events import FALLEN_TRUNK_HEIGHT_M, STAND_HOLD_S, STANDING_TRUNK_HEIGHT_M, UPRIGHT_UP_Z
from training.envs.starts.fallen import fallen_states
from training.envs.getup_config import default_config   # envs.make's config of this task

STAGES = ("stage1", "stage2", "full")
START_KINDS = ("fallen", "kneeling", "standing")


class GetupBase(base.T1Env):
    """Starts (fallen / kneeling / standing), observation and bookkeeping of the getup tasks."""

    def __init__(self, config: config_dict.ConfigDict, config_overrides: dict | None = None, make_env=None):
        super().__init__(config, config_overrides, make_env)
        cfg = self._config
        probs = jnp.asarray(self.start_probabilities(), dtype=jnp.float32)
        if probs.shape != (3,) or bool(jnp.any(probs < 0)) or abs(float(probs.sum()) - 1.0) > 1e-6:
            raise ValueError(f"start_probs must be 3 non-negative numbers summing to 1 "
                             f"(fallen, kneeling, standing), got {self.start_probabilities()}")
        self._start_logits = jnp.log(probs)
        if float(probs[0]) > 0:
            qpos, qvel = self.fallen_starts(int(cfg.fallen.bank_starts), int(cfg.fallen.seed))
        else:  # no fallen starts: skip the host precomputation
            qpos, qvel = self._home_qpos[None], jnp.zeros((1, self._mj_model.nv))
        self._fallen_qpos, self._fallen_qvel = jnp.asarray(qpos), jnp.asarray(qvel)
        # jax float32 scalars (strong types: no jit retrace)
        self._kneel_targets = jnp.asarray(self._keyframe_heights(self._kneel_qpos), jnp.float32)
        self._standing_targets = jnp.asarray(cfg.standing_targets_m, jnp.float32)
        if "obs_noise_scale" in cfg:   # the getup tasks (not the unified env, which uses the joystick's noise)
            # seed §4.6: the same U(−1, 1) range on every entry, whatever its unit (base.py scales per term)
            self._noise_scale = jnp.ones_like(self._noise_scale)

    def fallen_starts(self, num: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """(qpos, qvel) of this env's fallen starts for seeds seed … seed + num − 1 (training and evaluation):
        after the runtime's PREPARE ramp, under this env's supervisor settings."""
        return fallen_states(num, seed, float(self._config.fallen.prepare_s), self.host_supervisor())

    def host_supervisor(self) -> tuple[float, float]:
        """Rule R6 as the host rollouts of the start banks take it: (max target speed [rad/s], range fraction)."""
        step_per_substep, fraction = self._supervisor_settings(self._config)
        return step_per_substep / float(self._config.sim_dt), fraction

    def _keyframe_heights(self, qpos) -> tuple[float, float]:
        """(trunk, waist) origin heights [m] of a keyframe, from the model's kinematics."""
        data = mujoco.MjData(self._mj_model)
        data.qpos[:] = np.asarray(qpos)
        mujoco.mj_kinematics(self._mj_model, data)
        return float(data.xpos[self._trunk_id, 2]), float(data.xpos[self._waist_id, 2])

    def height_orientation(self, info, targets):
        return G.height_orientation_reward(info["trunk_height"], info["waist_height"], info["up_z"],
                                           targets[0], targets[1])

    def full_task_rewards(self, q, info, gate_ok):
        """(Height, Pose) Rewards of the full task (§4.8, gated) at joint angles q [rad]."""
        kneel_h = self.height_orientation(info, self._kneel_targets)
        stand_h = self.height_orientation(info, self._standing_targets)
        kneel_p, stand_p = G.pose_reward(q, self._kneel_qpos[7:]), G.pose_reward(q, self._default_pose)
        return G.gated_height_reward(gate_ok, kneel_h, stand_h), G.gated_pose_reward(gate_ok, kneel_p, stand_p)

    @staticmethod
    def standing(info):
        return (info["trunk_height"] >= STANDING_TRUNK_HEIGHT_M) & (info["up_z"] >= UPRIGHT_UP_Z)

    def energy_cost(self, data):
        """§4.7's energy cost Σ|v·τ/τmax| of the state after the step (before its weight)."""
        return G.energy_cost(data.qvel[6:], data.actuator_force, self._tau_limit)

    @staticmethod
    def success_from(kind: str, success, info):
        """`success` counted only in episodes that started as START_KINDS' `kind`."""
        return success * (info["start_kind"] == START_KINDS.index(kind))

    def start_probabilities(self):
        return list(self._config.start_probs)

    def _start_state(self, rng):
        """(qpos, qvel, kind index) of a random start."""
        k_kind, k_idx = jax.random.split(rng)
        kind = jax.random.categorical(k_kind, self._start_logits)
        idx = jax.random.randint(k_idx, (), 0, self._fallen_qpos.shape[0])
        qpos = jnp.stack([self._fallen_qpos[idx], self._kneel_qpos, self._home_qpos])[kind]
        qvel = jnp.stack([self._fallen_qvel[idx], jnp.zeros_like(self._fallen_qvel[0]),
                          jnp.zeros_like(self._fallen_qvel[0])])[kind]
        return qpos, qvel, kind

    def _noise_level(self):
        return self._config.obs_noise_scale

    def _observe(self, data, info, rng, extra) -> dict[str, jax.Array]:
        s = self.observation_state(data, jnp.zeros(3), info["last_act"], obsdef.initial_gait_phase(jnp))
        noisy, clean = self.actor_observation(s, rng, self._noise_level())
        return {"state": noisy, "privileged_state": jnp.concatenate([self.privileged_base(data, clean), extra])}

    def _physics(self, state, action):
        info = dict(state.info)
        info["rng"], k_obs = jax.random.split(info["rng"])
        data, info["runtime_target"] = self.physics_step(state.data, self.motor_targets(action),
                                                         info["runtime_target"])
        info.update(self.body_readings(data))
        info["up"] = self.up_vector(data)
        return data, info, k_obs

    def _privileged_extra(self, info):
        """Critic extras of the getup tasks: gate met, ‖u − e_z‖."""
        return jnp.stack([self._critic_gate(info).astype(jnp.float32), G.up_error(info["up"])])

    def _critic_gate(self, info):
        return G.gate(info["trunk_height"], info["up"])

    def _start_info(self, rng, data, kind) -> dict:
        return {"rng": rng, "last_act": jnp.zeros(base.NUM_JOINTS), "start_kind": kind.astype(jnp.int32),
                "runtime_target": self.start_target(data.qpos), "up": self.up_vector(data),
                **self.body_readings(data)}


class Getup(GetupBase):
    """The keyframe-curriculum getup expert."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)
        if self._config.stage not in STAGES:
            raise ValueError(f"getup stage {self._config.stage!r} unknown; valid: {', '.join(STAGES)}")
        self._kneel_pose = self._kneel_qpos[7:]
        rc = self._config.reverse_curriculum
        self._path_bank = None
        if not (0.0 <= rc.max_progress <= kneeling_path.PATH_END and 0.0 <= rc.kneel_prob <= 1.0):
            raise ValueError(f"reverse_curriculum: max_progress must be in [0, {kneeling_path.PATH_END}] and "
                             f"kneel_prob in [0, 1], got {rc.max_progress} and {rc.kneel_prob}")
        if self._config.stage == "stage2" and rc.max_progress > 0:
            starts = kneeling_path.bank_range(rc.min_progress, rc.max_progress, int(rc.bank_size))
            bank = kneeling_path.path_bank(self._mj_model, np.asarray(self._home_qpos), np.asarray(self._kneel_qpos),
                                        rc.left_leg_waypoints, int(rc.bank_size))
            self._path_bank = jnp.asarray(bank[starts], jnp.float32)
        self._fallen_banks = self._load_fallen_banks()
        self._stand_hold_ticks = int(round(STAND_HOLD_S / self.dt))
        self._stage1_gate_reward = float(self._config.stage1_gate_reward)
        self._stage1_upright_reward = float(self._config.stage1_upright_reward)
        self._action_size = sagittal.action_size(self._config.action_space)
        self._expansion = (jnp.asarray(sagittal.expansion()) if self._config.action_space == "sagittal" else None)
        for key in ("stage1_gate_reward", "stage1_upright_reward", "stage1_drop_below_m"):
            if float(self._config[key]) < 0.0:
                raise ValueError(f"{key} must be >= 0, got {self._config[key]}")

    def _load_fallen_banks(self) -> list[tuple[float, tuple[jax.Array, jax.Array]]]:
        """(share of the fallen starts, (qpos, qvel)) of the configured start sources (starts/)."""
        return [(prob, tuple(jnp.asarray(x) for x in bank))
                for prob, bank in starts.fallen_share_banks(self, self._config)]

    def _start_state(self, rng):
        """The stage's start; with the reverse curriculum on, a stage-2 start drawn along the start path; with
        start banks (starts/), a share of the fallen ones from those banks."""
        if self._path_bank is None and not self._fallen_banks:
            return super()._start_state(rng)
        if self._path_bank is None:
            k_start, k_use, k_idx = jax.random.split(rng, 3)
            qpos, qvel, kind = super()._start_state(k_start)
            u, lo = jax.random.uniform(k_use), 0.0
            for prob, (bank_qpos, bank_qvel) in self._fallen_banks:   # each bank its slice of [0, 1)
                use = (kind == 0) & (u >= lo) & (u < lo + prob)
                idx = jax.random.randint(k_idx, (), 0, bank_qpos.shape[0])
                qpos, qvel = jnp.where(use, bank_qpos[idx], qpos), jnp.where(use, bank_qvel[idx], qvel)
                lo += prob
            return qpos, qvel, kind
        k_kneel, k_idx = jax.random.split(rng)
        at_kneel = jax.random.uniform(k_kneel) < self._config.reverse_curriculum.kneel_prob
        idx = jax.random.randint(k_idx, (), 0, self._path_bank.shape[0])
        qpos = jnp.where(at_kneel, self._kneel_qpos, self._path_bank[idx])
        # start_kind: the kneel is "kneeling"; a path start is counted with "standing" (it is on the way up)
        return qpos, jnp.zeros(self._mj_model.nv), jnp.where(at_kneel, 1, 2).astype(jnp.int32)

    def _start_info(self, rng, data, kind) -> dict:
        info = super()._start_info(rng, data, kind)
        info["gate"] = self.gate_state(info, jnp.zeros((), dtype=bool))
        info["gate_met"] = jnp.zeros((), dtype=bool)    # §4.8's gate has held at a step since the reset
        info["gate_height_met"] = jnp.zeros((), dtype=bool)   # the trunk has been at the gate's height since
        info["rise_track"] = G.rise_track_start(info["trunk_height"])
        return info

    def gate_state(self, info, was_on) -> jax.Array:
        """The gate the full task's rewards use: §4.8's per-step condition, latched from the step it first
        holds until the trunk is down (config.gate_latches; the module docstring says why)."""
        now = G.gate(info["trunk_height"], info["up"])
        if not self._config.gate_latches:
            return now
        return (now | was_on) & (info["trunk_height"] >= FALLEN_TRUNK_HEIGHT_M)

    def _critic_gate(self, info):
        return info["gate"]      # the reward's phase, which the critic cannot infer from one state

    def start_probabilities(self):
        stage = self._config.stage
        if stage in ("stage1", "stage2"):
            return list(self._config[f"{stage}_start_probs"])
        return list(self._config.start_probs)

    def reset(self, rng: jax.Array) -> mjx_env.State:
        rng, k_start, k_obs = jax.random.split(rng, 3)
        qpos, qvel, kind = self._start_state(k_start)
        data = self.make_data(qpos, qvel)
        info = self._start_info(rng, data, kind)
        obs = self._observe(data, info, k_obs, self._privileged_extra(info))
        metrics = {k: jnp.zeros(()) for k in self.metric_names()}
        return mjx_env.State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    @staticmethod
    def metric_names():
        return ("reward/height", "reward/pose", "reward/energy", "failed_rises", "gate", "gate_reached", "success",
                "success_from_kneel", "success_from_fallen")

    def reward_terms(self, data, info) -> dict[str, jax.Array]:
        """Height and Pose Rewards (the stage's form) and the energy cost of the state after the step."""
        q, stage = data.qpos[7:], self._config.stage
        if stage == "stage1":
            kneel_h = self.height_orientation(info, self._kneel_targets)
            height = G.kneel_height_reward(
                G.gate(info["trunk_height"], info["up"]), kneel_h, self._stage1_gate_reward,
                G.upright_at_gate_height(info["trunk_height"], info["up"]), self._stage1_upright_reward)
            pose = G.pose_reward(q, self._kneel_pose)
        elif stage == "stage2":
            height, pose = self.height_orientation(info, self._standing_targets), G.pose_reward(q, self._default_pose)
        else:
            height, pose = self.full_task_rewards(q, info, info["gate"])
        return {"height": height, "pose": pose, "gate": info["gate"], "energy": self.energy_cost(data)}

    @property
    def action_size(self) -> int:
        return self._action_size

    def full_action(self, action: jax.Array) -> jax.Array:
        """The 23 joints' action of the policy's (envs/sagittal.py when config.action_space is sagittal)."""
        return action if self._expansion is None else self._expansion @ action

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
        action = self.full_action(action)
        data, info, k_obs = self._physics(state, action)
        info["gate"] = self.gate_state(info, state.info["gate"])
        gate_now = G.gate(info["trunk_height"], info["up"])
        info["gate_met"] = state.info["gate_met"] | gate_now
        info["gate_height_met"] = state.info["gate_height_met"] | G.at_gate_height(info["trunk_height"])
        terms = self.reward_terms(data, info)
        scaled = {"height": terms["height"], "pose": terms["pose"],
                  "energy": -self._config.energy_weight * terms["energy"]}
        info["rise_track"], failed = G.rise_track_step(state.info["rise_track"], info["trunk_height"],
                                                       self.standing(info), self._stand_hold_ticks)
        reward = sum(scaled.values()) * self.dt
        info["last_act"] = action
        obs = self._observe(data, info, k_obs, self._privileged_extra(info))
        metrics = dict(state.metrics)   # keep what wrappers added (brax's EvalWrapper adds "reward")
        metrics.update({f"reward/{k}": v.astype(jnp.float32) for k, v in scaled.items()})
        metrics["gate"] = terms["gate"].astype(jnp.float32)
        # 1 at the first step the gate holds: an episode's sum is whether it met the gate (stage 1's success)
        metrics["gate_reached"] = (gate_now & ~state.info["gate_met"]).astype(jnp.float32)
        metrics["failed_rises"] = failed.astype(jnp.float32)
        metrics["success"] = (terms["gate"] if self._config.stage == "stage1"
                              else self.standing(info)).astype(jnp.float32)
        # standing in an episode that started at the kneel (with the reverse curriculum, the share that counts)
        metrics["success_from_kneel"] = self.success_from("kneeling", metrics["success"], info)
        metrics["success_from_fallen"] = self.success_from("fallen", metrics["success"], info)   # the full task's aim
        done = self.invalid(data) | self.fell_from_kneel(info)
        return state.replace(data=data, obs=obs, reward=reward, done=done.astype(jnp.float32), metrics=metrics,
                             info=info)

    def fell_from_kneel(self, info) -> jax.Array:
        """The terminations besides non-finite physics (module docstring): stage 2's trunk below the fall height
        or tilted past the fall tilt; stage 1's trunk dropped stage1_drop_below_m below the gate's height after
        reaching it."""
        cfg = self._config
        if cfg.stage == "stage1" and cfg.stage1_drop_below_m > 0:
            return info["gate_height_met"] & (info["trunk_height"] < G.GATE_HEIGHT_M - cfg.stage1_drop_below_m)
        if cfg.stage != "stage2":
            return jnp.zeros((), dtype=bool)
        return (info["trunk_height"] < cfg.stage2_fall_trunk_height_m) | (info["up_z"] < cfg.stage2_fall_up_z)
