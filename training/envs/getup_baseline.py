"""Baseline getup: the reward-only standing policy the seed compares the keyframe curriculum against.

Same model (full-body collision), gains, action map and observation (TERMS_GETUP) as the getup expert,
same starts as its full task (fallen / kneeling / standing with start_probs), but no keyframes, no
curriculum, no gate bonuses. Reward per control step (× ctrl_dt):
    w_height·exp(−|h − h_home| / 0.1 m) + w_upright·(1 + up_z)/2
    − w_action_rate·‖a − a_prev‖² − w_joint_vel·‖dq‖²
with the height/orientation functions shared with the expert (getup_rewards.py). "success" is the same
home gate as the expert's full task, so the two are compared on one definition.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict
from mujoco_playground._src import mjx_env

from training.envs import base
from training.envs import getup_rewards as G
from training.envs.getup import GetupBase, getup_common_config


def default_config() -> config_dict.ConfigDict:
    cfg = getup_common_config()
    cfg.reward = config_dict.create(height=1.0, upright=1.0, action_rate=0.01, joint_vel=1e-4)
    return cfg


class GetupBaseline(GetupBase):
    """Reward-only standing policy."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None):
        super().__init__(config if config is not None else default_config(), config_overrides)

    def _extra(self):
        return jnp.stack([self._home_trunk_h, jnp.ones((), jnp.float32)])

    def reset(self, rng: jax.Array) -> mjx_env.State:
        rng, k_start, k_obs = jax.random.split(rng, 3)
        qpos, qvel, kind = self._start_state(k_start)
        data = self.make_data(qpos, qvel)
        info = {"rng": rng, "last_act": jnp.zeros(base.NUM_JOINTS), "start_kind": kind.astype(jnp.int32),
                **self.body_readings(data)}
        obs = self._observe(data, info, k_obs, self._extra())
        metrics = {k: jnp.zeros(()) for k in ("reward/height", "reward/upright", "reward/action_rate",
                                               "reward/joint_vel", "success")}
        return mjx_env.State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
        last_act = state.info["last_act"]
        data, info, k_obs = self._physics(state, action)
        w = self._config.reward
        h, up_z = info["trunk_height"], info["up_z"]
        scaled = {"height": w.height * G.height_reward(h, self._home_trunk_h),
                  "upright": w.upright * G.orientation_reward(up_z),
                  "action_rate": -w.action_rate * G.action_rate_cost(action, last_act),
                  "joint_vel": -w.joint_vel * G.joint_velocity_cost(data.qvel[6:])}
        reward = sum(scaled.values()) * self.dt
        info["last_act"] = action
        obs = self._observe(data, info, k_obs, self._extra())
        metrics = {f"reward/{k}": v.astype(jnp.float32) for k, v in scaled.items()}
        metrics["success"] = G.gate(h, self._home_trunk_h, up_z).astype(jnp.float32)
        done = self.invalid(data).astype(jnp.float32)
        return state.replace(data=data, obs=obs, reward=reward, done=done, metrics=metrics, info=info)
