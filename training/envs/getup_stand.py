"""Getup stage 2, kneel → stand (thesis §4.5): Height = HO(standing targets: the contract's torso and waist
targets), Pose = pose(q, q_init), from the kneel keyframe. The gate's 1.83 / 0.6 bonuses and 100· weight belong
to the full task (§4.8, getup.py): without a gate they pay standing-like joint angles in any posture.

Ours: an episode ends when the robot leaves the kneel downward (trunk below fall_trunk_height_m, or up_z below
fall_up_z), because stage 2's Pose pays straight legs in any posture, lying or leaning back included. Off by
default: the reverse curriculum (`reverse_curriculum`, starts/kneeling_path.py) draws starts along a path from
standing to the kneel; `rise_kneels` (starts/rise_kneels.py) starts a share of episodes where the chain's rise hands
over, at the kneel band or §4.8's gate, with the rise's velocities.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from ml_collections import config_dict

from messages import contract
from training.envs import getup_base, starts
from training.envs import getup_rewards as G
from training.envs.starts import kneeling_path, rise_kneels


def default_config() -> config_dict.ConfigDict:
    cfg = getup_base.base_config()
    cfg.start_probs = [0.0, 1.0, 0.0]      # (fallen, kneeling, standing): the seed's stage 2 starts kneeling
    cfg.reward = config_dict.create(scales=config_dict.create(height=1.0, pose=1.0, energy=0.0))
    cfg.fall_trunk_height_m = contract.FALLEN_TRUNK_HEIGHT_M   # the episode ends with the trunk below this [m]
    cfg.fall_up_z = 0.7                    # ... or with the trunk's up_z below this (46° of tilt)
    starts.add_config_groups(cfg, "getup_stand")   # fallen starts, the reverse curriculum
    return cfg


class GetupStand(getup_base.GetupTask):
    """Stand up from the kneel keyframe."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)
        rc = self._config.reverse_curriculum
        if not (0.0 <= rc.max_progress <= kneeling_path.PATH_END and 0.0 <= rc.kneel_prob <= 1.0):
            raise ValueError(f"reverse_curriculum: max_progress must be in [0, {kneeling_path.PATH_END}] and "
                             f"kneel_prob in [0, 1], got {rc.max_progress} and {rc.kneel_prob}")
        self._path_bank = None
        if rc.max_progress > 0:
            rows = kneeling_path.bank_range(rc.min_progress, rc.max_progress, int(rc.bank_size))
            bank = kneeling_path.path_bank(self._mj_model, np.asarray(self._home_qpos), np.asarray(self._kneel_qpos),
                                           rc.left_leg_waypoints, int(rc.bank_size))
            self._path_bank = jnp.asarray(bank[rows], jnp.float32)
        kneels = self._config.rise_kneels
        if not 0.0 <= kneels.prob <= 1.0:
            raise ValueError(f"rise_kneels.prob must be in [0, 1], got {kneels.prob}")
        self._kneel_bank = None
        if kneels.prob > 0:
            if not kneels.rise_policy:
                raise ValueError("rise_kneels.prob > 0 needs rise_kneels.rise_policy")
            bank = rise_kneels.rise_kneels_bank(make_env, kneels, float(self._config.fallen.prepare_s))
            self._kneel_bank = tuple(jnp.asarray(x, jnp.float32) for x in bank)

    def _reward_terms(self, data, info) -> dict[str, jax.Array]:
        return {"height": self.height_orientation(info, self._standing_targets),
                "pose": G.pose_reward(data.qpos[7:], self._default_pose),
                "energy": self.energy_cost(data)}

    def _terminated(self, info) -> jax.Array:
        cfg = self._config
        return (info["trunk_height"] < cfg.fall_trunk_height_m) | (info["up_z"] < cfg.fall_up_z)

    def _start_state(self, rng):
        """With the reverse curriculum on, a start drawn along the start path or at the kneel; with rise_kneels on,
        that share of starts where the rise hands over (counted as kneeling, its bank row kept)."""
        if self._kneel_bank is None:
            return self._path_start(rng)
        k_path, k_use, k_idx = jax.random.split(rng, 3)
        qpos, qvel, kind, row = self._path_start(k_path)
        use = jax.random.uniform(k_use) < self._config.rise_kneels.prob
        idx = jax.random.randint(k_idx, (), 0, self._kneel_bank[0].shape[0])
        return (jnp.where(use, self._kneel_bank[0][idx], qpos), jnp.where(use, self._kneel_bank[1][idx], qvel),
                jnp.where(use, 1, kind).astype(jnp.int32), jnp.where(use, idx, row).astype(jnp.int32))

    def _path_start(self, rng):
        if self._path_bank is None:
            return super()._start_state(rng)
        k_kneel, k_idx = jax.random.split(rng)
        at_kneel = jax.random.uniform(k_kneel) < self._config.reverse_curriculum.kneel_prob
        idx = jax.random.randint(k_idx, (), 0, self._path_bank.shape[0])
        qpos = jnp.where(at_kneel, self._kneel_qpos, self._path_bank[idx])
        # start_kind: the kneel is "kneeling"; a path start is counted with "standing" (it is on the way up)
        kind = jnp.where(at_kneel, 1, 2).astype(jnp.int32)
        return qpos, jnp.zeros(self._mj_model.nv), kind, jnp.asarray(-1, jnp.int32)
