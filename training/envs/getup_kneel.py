"""Getup stage 1, fallen → kneel (thesis §4.5): Height = HO(kneel targets), Pose = pose(q, q_kneel), from fallen
starts, episodes that end only on non-finite physics: the seed's stage 1 at the default config.

Ours, off by default (the recipe's stage-1 settings set them, training/recipes/getup_keyframe.py):
`reward.scales.gate` per step while §4.8's gate holds and `reward.scales.upright` × a slope toward the gate's
tilt at its height (getup_rewards.upright_at_gate_height) pay the gate itself, which holding the kneel keyframe's
joint angles under PD misses by a sag of 1.25° that the pose term pays 0.999 of its best; `demo_starts`
(starts/demos.py) replaces a share of the fallen starts by states of the planner's rises.
The gate the task carries (critic input, metric `gate`, `success`) latches from its first hold until the trunk
is down: the kneel reached and not lost.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict

from training.envs import getup_base, starts
from training.envs import getup_rewards as G


def default_config() -> config_dict.ConfigDict:
    cfg = getup_base.base_config()
    cfg.start_probs = [1.0, 0.0, 0.0]      # (fallen, kneeling, standing): the seed's stage 1 starts fallen
    cfg.reward = config_dict.create(scales=config_dict.create(height=1.0, pose=1.0, gate=0.0, upright=0.0,
                                                              energy=0.0))
    starts.add_config_groups(cfg, "getup_kneel")   # fallen starts, demonstration starts
    return cfg


class GetupKneel(getup_base.GetupTask):
    """Rise from fallen to the kneel keyframe."""

    def _reward_terms(self, data, info) -> dict[str, jax.Array]:
        return {"height": self.height_orientation(info, self._kneel_targets),
                "pose": G.pose_reward(data.qpos[7:], self._kneel_qpos[7:]),
                "gate": G.gate(info["trunk_height"], info["up_z"]).astype(jnp.float32),
                "upright": G.upright_at_gate_height(info["trunk_height"], info["up"]),
                "energy": self.energy_cost(data)}

    def _gate_state(self, gate_now, was_on, info) -> jax.Array:
        return G.latched_gate(gate_now, was_on, info["trunk_height"])

    def _success(self, info) -> jax.Array:
        return info["gate"]
