"""Getup expert: the seed's keyframe curriculum on the full-body-collision model.

Stages (config.stage): "stage1" fallen → kneel keyframe (starts fallen), "stage2" kneel → stand (home)
(starts kneeling), "full" (fine-tuned from the stage-2 checkpoint) starts fallen / kneeling / standing with
config.start_probs = (0.4, 0.4, 0.2) and targets kneel until the kneel gate is passed, then home (see
getup_rewards.select_target). Fallen starts come from envs.fallen_states(fallen_bank_size,
fallen_seed), precomputed on the host. The gate, bonuses, pose and energy terms are in
getup_rewards.py (formulas and the reading of the seed in its docstring). Fine-tunes: energy_weight > 0
(energy), obs_noise_scale > 0 (observation noise U(−1, 1)·obs_noise_scale·term scale).
Actor obs = TERMS_GETUP (gyro, gravity, joint_pos, joint_vel, last_action). No termination except
non-finite physics: a getup episode runs its whole length (10 s by default).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict
from mujoco_playground._src import mjx_env

from training import observation as obsdef
from training.envs import base
from training.envs import getup_rewards as G
from training.envs.fallen import fallen_states

STAGES = ("stage1", "stage2", "full")
START_KINDS = ("fallen", "kneeling", "standing")
PRIVILEGED_EXTRA = 2  # target trunk height [m], target-is-home flag


def getup_common_config() -> config_dict.ConfigDict:
    """Settings the getup expert and the baseline share (starts, model, observation)."""
    cfg = base.base_config()
    cfg.collision = "full_body"
    cfg.episode_length = 500
    cfg.obs_terms = [list(t) for t in obsdef.TERMS_GETUP]
    cfg.noise.level = 1.0
    cfg.obs_noise_scale = 0.0            # multiplies noise.scales; 0 = off (robustness fine-tune sets it)
    cfg.start_probs = [0.4, 0.4, 0.2]    # (fallen, kneeling, standing) for the full task
    cfg.fallen_bank_size = 128           # distinct precomputed fallen starts
    cfg.fallen_seed = 0
    return cfg


def default_config() -> config_dict.ConfigDict:
    cfg = getup_common_config()
    cfg.stage = "full"
    cfg.energy_weight = 0.0
    cfg.reward = config_dict.create(height=1.0, orientation=1.0, pose=1.0)
    return cfg


class GetupBase(base.T1Env):
    """Starts (fallen / kneeling / standing), observation and bookkeeping of the getup tasks."""

    def __init__(self, config: config_dict.ConfigDict, config_overrides: dict | None = None):
        super().__init__(config, config_overrides)
        cfg = self._config
        probs = jnp.asarray(self.start_probabilities(), dtype=jnp.float32)
        if probs.shape != (3,) or bool(jnp.any(probs < 0)) or abs(float(probs.sum()) - 1.0) > 1e-6:
            raise ValueError(f"start_probs must be 3 non-negative numbers summing to 1 "
                             f"(fallen, kneeling, standing), got {list(cfg.start_probs)}")
        self._start_logits = jnp.log(probs)
        if float(probs[0]) > 0:
            qpos, qvel = fallen_states(int(cfg.fallen_bank_size), int(cfg.fallen_seed))
        else:  # no fallen starts: skip the host precomputation
            qpos, qvel = self._home_qpos[None], jnp.zeros((1, self._mj_model.nv))
        self._fallen_qpos, self._fallen_qvel = jnp.asarray(qpos), jnp.asarray(qvel)
        self._home_trunk_h = self._home_qpos[2]    # jax float32 scalars (strong types: no jit retrace)
        self._kneel_trunk_h = self._kneel_qpos[2]

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
        return self._config.noise.level * self._config.obs_noise_scale

    def _observe(self, data, info, rng, extra) -> dict[str, jax.Array]:
        s = self.observation_state(data, jnp.zeros(3), info["last_act"], obsdef.initial_gait_phase(jnp))
        noisy, clean = self.actor_observation(s, rng, self._noise_level())
        return {"state": noisy, "privileged_state": jnp.concatenate([self.privileged_base(data, clean), extra])}

    def _physics(self, state, action):
        info = dict(state.info)
        info["rng"], k_obs = jax.random.split(info["rng"])
        data = self.physics_step(state.data, self.motor_targets(action))
        info.update(self.body_readings(data))
        return data, info, k_obs


class Getup(GetupBase):
    """The keyframe-curriculum getup expert."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None):
        super().__init__(config if config is not None else default_config(), config_overrides)
        if self._config.stage not in STAGES:
            raise ValueError(f"getup stage {self._config.stage!r} unknown; valid: {', '.join(STAGES)}")
        self._kneel_pose = self._kneel_qpos[7:]

    def start_probabilities(self):
        stage = self._config.stage
        return {"stage1": [1.0, 0.0, 0.0], "stage2": [0.0, 1.0, 0.0]}.get(stage, list(self._config.start_probs))

    def targets(self, reached_kneel):
        """(target trunk height [m], target joint angles [rad], target is home) for the current stage."""
        kneel_stage = jnp.asarray(self._config.stage == "stage1")
        h = G.select_target(reached_kneel, kneel_stage, self._kneel_trunk_h, self._home_trunk_h)
        q = G.select_target(reached_kneel, kneel_stage, self._kneel_pose, self._default_pose)
        return h, q, ~(kneel_stage | ~reached_kneel)

    def reset(self, rng: jax.Array) -> mjx_env.State:
        rng, k_start, k_obs = jax.random.split(rng, 3)
        qpos, qvel, kind = self._start_state(k_start)
        data = self.make_data(qpos, qvel)
        # Stage 2 starts past the kneel stage; in the full task a kneeling / standing start is too.
        reached = (kind > 0) | jnp.asarray(self._config.stage == "stage2")
        info = {"rng": rng, "last_act": jnp.zeros(base.NUM_JOINTS), "reached_kneel": reached,
                "start_kind": kind.astype(jnp.int32), **self.body_readings(data)}
        obs = self._observe(data, info, k_obs, self._privileged_extra(reached))
        metrics = {k: jnp.zeros(()) for k in self.metric_names()}
        return mjx_env.State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    @staticmethod
    def metric_names():
        return ("reward/height", "reward/orientation", "reward/pose", "reward/height_bonus",
                "reward/pose_bonus", "reward/energy", "success", "reached_kneel")

    def _privileged_extra(self, reached_kneel):
        h, _, home = self.targets(reached_kneel)
        return jnp.stack([h, home.astype(jnp.float32)])

    def reward_terms(self, data, info) -> dict[str, jax.Array]:
        """Unweighted terms for the state after the step (gate uses the target in force)."""
        h_t, q_t, _ = self.targets(info["reached_kneel"])
        h, up_z, q = info["trunk_height"], info["up_z"], data.qpos[7:]
        pose_r = G.pose_reward(q, q_t)
        ok = G.gate(h, h_t, up_z)
        return {"height": G.height_reward(h, h_t), "orientation": G.orientation_reward(up_z), "pose": pose_r,
                "height_bonus": G.height_bonus(ok), "pose_bonus": G.pose_bonus(ok, pose_r),
                "energy": G.energy_cost(data.qvel[6:], data.actuator_force, self._tau_limit), "gate": ok}

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
        data, info, k_obs = self._physics(state, action)
        terms = self.reward_terms(data, info)
        w = self._config.reward
        scaled = {"height": w.height * terms["height"], "orientation": w.orientation * terms["orientation"],
                  "pose": w.pose * terms["pose"], "height_bonus": terms["height_bonus"],
                  "pose_bonus": terms["pose_bonus"], "energy": -self._config.energy_weight * terms["energy"]}
        reward = sum(scaled.values()) * self.dt
        _, _, target_home = self.targets(info["reached_kneel"])
        success = terms["gate"] & target_home
        # Latch the stage switch AFTER rewarding this step against the kneel target.
        info["reached_kneel"] = info["reached_kneel"] | terms["gate"]
        info["last_act"] = action
        obs = self._observe(data, info, k_obs, self._privileged_extra(info["reached_kneel"]))
        metrics = {f"reward/{k}": v.astype(jnp.float32) for k, v in scaled.items()}
        metrics["success"] = (terms["gate"] if self._config.stage == "stage1" else success).astype(jnp.float32)
        metrics["reached_kneel"] = info["reached_kneel"].astype(jnp.float32)
        done = self.invalid(data).astype(jnp.float32)
        return state.replace(data=data, obs=obs, reward=reward, done=done, metrics=metrics, info=info)
