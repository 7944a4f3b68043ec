"""Getup stage 0, on the back or side → face down (ours, not the seed's): the keyframe getup's chain is roll → rise
→ stand, because the face-down rise meets §4.8's gate reliably and the rise from the back does not. A person on
their back turns onto hands and knees first; HumanUP trains rolling over as a task of its own.

Rewards (getup_rewards.py), from fallen starts (the recipe weights out the face-down ones: `fallen.side_weights`):
  turn   (1 − f_z) / 2 of the trunk's forward axis' world z f_z: 0 on the back, 1 face down (dense along the turn);
  rolled per step while common/events.rolled_face_down holds (the chain's hand-over to the rise);
  pose   the seed's pose term toward the default pose while face down: the rise's face-down starts lie in it
         (after the runtime's PREPARE ramp), so the roll ends where the rise has learnt to start;
  energy §4.7's cost, off by default.
`success` is the hand-over condition; episodes end only on non-finite physics.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict

from common import events
from training.envs import getup_base, starts
from training.envs import getup_rewards as G


def default_config() -> config_dict.ConfigDict:
    cfg = getup_base.base_config()
    cfg.episode_length = 250               # 5 s at 50 Hz: a roll takes 1–3 s
    cfg.start_probs = [1.0, 0.0, 0.0]      # (fallen, kneeling, standing)
    cfg.reward = config_dict.create(scales=config_dict.create(turn=1.0, rolled=2.0, pose=1.0, energy=0.0))
    starts.add_config_groups(cfg, "getup_roll")   # the recipe draws no face-down starts (fallen.side_weights)
    return cfg


class GetupRoll(getup_base.GetupTask):
    """Turn from the back or side onto the front, and lie there."""

    def _task_info(self, info, data) -> dict:
        forward_z = self.forward_z(data)
        ang_speed = jnp.linalg.norm(self.sensor(data, "gyro"))  # [rad/s]
        return {"forward_z": forward_z,
                "rolled": events.rolled_face_down(forward_z, info["trunk_height"], ang_speed, jnp)}

    def _reward_terms(self, data, info) -> dict[str, jax.Array]:
        face_down = (info["forward_z"] < -events.FACING_Z).astype(jnp.float32)
        return {"turn": G.turn_reward(info["forward_z"]), "rolled": info["rolled"].astype(jnp.float32),
                "pose": face_down * G.pose_reward(data.qpos[7:], self._default_pose),
                "energy": self.energy_cost(data)}

    def _success(self, info) -> jax.Array:
        return info["rolled"]
