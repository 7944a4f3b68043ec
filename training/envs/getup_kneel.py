"""Getup stage 1, fallen → kneel (thesis §4.5): Height = HO(kneel targets), Pose = pose(q, q_kneel), from fallen
starts, episodes that end only on non-finite physics: the seed's stage 1 at the default config.

Ours, off by default (the recipe's backplay sets them, training/recipes/getup_keyframe.py): `reward.scales.gate`
per step while §4.8's gate holds and `reward.scales.upright` × a slope toward the gate's tilt at its height
(getup_rewards.upright_at_gate_height) pay the gate itself, which holding the kneel keyframe's joint angles under
PD misses by a sag of 1.25° that the pose term pays 0.999 of its best; `drop_below_gate_m` > 0 ends an episode
once the trunk, having reached the gate's height, drops that far below it (DeepMimic's early termination);
`demo_starts` (starts/demos.py) replaces a share of the fallen starts by states of the planner's rises.
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
    cfg.drop_below_gate_m = 0.0            # [m] below the gate's height after reaching it: the end (0 = never)
    starts.add_config_groups(cfg, "getup_kneel")   # fallen starts, demonstration starts
    return cfg


class GetupKneel(getup_base.GetupTask):
    """Rise from fallen to the kneel keyframe."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)
        if float(self._config.drop_below_gate_m) < 0.0:
            raise ValueError(f"drop_below_gate_m must be >= 0 [m], got {self._config.drop_below_gate_m}")

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

    def _terminated(self, info) -> jax.Array:
        drop_m = float(self._config.drop_below_gate_m)
        if drop_m == 0.0:
            return super()._terminated(info)
        return info["gate_height_met"] & (info["trunk_height"] < G.GATE_HEIGHT_M - drop_m)
