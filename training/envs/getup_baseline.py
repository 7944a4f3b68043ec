"""Baseline getup: the reward-only standing policy the seed compares the keyframe curriculum against (§4.4).

Same model, gains, action map and observation as the keyframe tasks; fallen starts by default (it rises straight
from the ground); no keyframe, no curriculum, no gate in its reward: Height = HO(h_torso, h_waist, u_z; the
contract's standing targets). `success` is the other tasks': standing by common/events.py's definition, so all are
compared on one. Ours (policies/getup_baseline/CARD.md says so where it is shown): `start_probs` may mix in
standing starts (a policy trained from fallen starts only never visits a quiet stance except by rising into
one), and `reward.scales.energy` < 0 charges §4.7's energy cost, which breaks its squat-jump cycle.
"""
from __future__ import annotations

import jax
from ml_collections import config_dict

from training.envs import getup_base, starts


def default_config() -> config_dict.ConfigDict:
    cfg = getup_base.base_config()
    cfg.start_probs = [1.0, 0.0, 0.0]      # (fallen, kneeling, standing): fallen starts only
    cfg.reward = config_dict.create(scales=config_dict.create(height=1.0, energy=0.0))
    starts.add_config_groups(cfg, "getup_baseline")   # its fallen starts: the keyframe tasks'
    return cfg


class GetupBaseline(getup_base.GetupTask):
    """Reward-only standing policy."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)

    def _reward_terms(self, data, info) -> dict[str, jax.Array]:
        return {"height": self.height_orientation(info, self._standing_targets), "energy": self.energy_cost(data)}
