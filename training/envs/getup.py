"""Getup, the gated full task (thesis §4.5, §4.8): from stage 2 on, fallen / kneeling / standing starts
(0.4 / 0.4 / 0.2) and the gated Height and Pose Rewards: below §4.8's gate the kneel's, once the gate holds
that step the standing's with its bonuses (getup_rewards.py). The gate is per step, as written: a gate latched
until the trunk is down pays a policy that meets it once and then tilts.
Ours, off by default: `knockdown_starts` (starts/knockdown.py) replaces a share of the fallen starts by the
joystick expert's landings after a push; `demo_starts` (starts/demos.py) by states along the planner's rises to
the kneel, where a student distilled from the keyframe chain learns the rise's last stretch to the gate.
The evaluations (`python -m training evaluate`) build this task for its fallen starts and physics.
"""
from __future__ import annotations

import jax
from ml_collections import config_dict

from training.envs import getup_base, starts


def default_config() -> config_dict.ConfigDict:
    cfg = getup_base.base_config()
    cfg.start_probs = [0.4, 0.4, 0.2]      # (fallen, kneeling, standing), §4.5
    cfg.reward = config_dict.create(scales=config_dict.create(height=1.0, pose=1.0, energy=0.0))
    starts.add_config_groups(cfg, "getup")   # fallen starts, knockdown landings, demonstration states
    return cfg


class Getup(getup_base.GetupTask):
    """Get up from fallen, kneeling or standing starts under the gated rewards."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)

    def _reward_terms(self, data, info) -> dict[str, jax.Array]:
        height, pose = self.gated_rewards(data.qpos[7:], info, info["gate"])
        return {"height": height, "pose": pose, "energy": self.energy_cost(data)}
