"""Baseline getup: the reward-only standing policy the seed compares the keyframe curriculum against (§4.4).

Same model (full-body collision), gains, action map and observation (TERMS_GETUP) as the getup expert;
fallen starts by default (issue 15: it rises straight from the ground); no keyframe, no curriculum, no gate. Its
reward is the seed's height & orientation reward toward standing (getup_rewards.py), per control step
(× ctrl_dt):  HO(h_torso, h_waist, u_z; torso 0.67 m, waist 0.55 m).
"success" is the expert's: standing by common/events.py's definition, so both are compared on one;
"success_from_fallen" counts it only in episodes that started fallen.

`start_probs` (fallen, kneeling, standing) may mix in standing starts (ours, not the seed's, which says
nothing of the baseline's starts): a policy trained from fallen starts only never visits a quiet stance
except by rising into one, and hops from standing starts (training/LESSONS.md); the seed's own full getup
uses a 0.2 standing share.
`energy_weight` > 0 subtracts that multiple of the seed's energy cost Σ|v·τ/τmax| (§4.7, per control step),
a fine-tune of ours: the seed uses it to tame the keyframe policy's high-effort motions, and here it is
what breaks the baseline's squat-jump cycle (hopping costs more energy than standing still). It lowers the
baseline's energy in Table 4.3, so the comparison with the keyframe policy says so.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict
from mujoco_playground._src import mjx_env

from training.envs import starts
from training.envs.getup import GetupBase
from training.envs.getup_config import getup_common_config

METRIC_NAMES = ("reward/height", "reward/energy", "success", "success_from_fallen")


def default_config() -> config_dict.ConfigDict:
    cfg = getup_common_config()
    cfg.start_probs = [1.0, 0.0, 0.0]     # fallen starts only
    cfg.energy_weight = 0.0               # × §4.7's energy cost; 0 = the seed's baseline (docstring)
    starts.add_config_groups(cfg, "getup_baseline")   # its fallen starts: the keyframe expert's
    return cfg


class GetupBaseline(GetupBase):
    """Reward-only standing policy."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)

    def reset(self, rng: jax.Array) -> mjx_env.State:
        rng, k_start, k_obs = jax.random.split(rng, 3)
        qpos, qvel, kind = self._start_state(k_start)
        data = self.make_data(qpos, qvel)
        info = self._start_info(rng, data, kind)
        obs = self._observe(data, info, k_obs, self._privileged_extra(info))
        metrics = {k: jnp.zeros(()) for k in METRIC_NAMES}
        return mjx_env.State(data, obs, jnp.zeros(()), jnp.zeros(()), metrics, info)

    def step(self, state: mjx_env.State, action: jax.Array) -> mjx_env.State:
        data, info, k_obs = self._physics(state, action)
        height = self.height_orientation(info, self._standing_targets)
        energy = -self._config.energy_weight * self.energy_cost(data)
        reward = (height + energy) * self.dt
        info["last_act"] = action
        obs = self._observe(data, info, k_obs, self._privileged_extra(info))
        metrics = dict(state.metrics)   # keep what wrappers added (brax's EvalWrapper adds "reward")
        metrics.update({"reward/height": height.astype(jnp.float32), "reward/energy": energy.astype(jnp.float32),
                        "success": self.standing(info).astype(jnp.float32)})
        # standing steps of the episodes that started fallen: the evaluation's aim when standing starts are mixed in
        metrics["success_from_fallen"] = self.success_from("fallen", metrics["success"], info)
        done = self.invalid(data).astype(jnp.float32)
        return state.replace(data=data, obs=obs, reward=reward, done=done, metrics=metrics, info=info)
