"""Getup stage 1, fallen → kneel (thesis §4.5): Height = HO(kneel targets), Pose = pose(q, q_kneel), from fallen
starts, episodes that end only on non-finite physics: the seed's stage 1 at the default config.

Ours, off by default (the recipe's backplay sets them, training/recipes/getup_keyframe.py): `reward.scales.gate`
per step while §4.8's gate holds and `reward.scales.upright` × a slope toward the gate's tilt at its height
(getup_rewards.upright_at_gate_height) pay the gate itself, which holding the kneel keyframe's joint angles under
PD misses by a sag of 1.25° that the pose term pays 0.999 of its best; `drop_below_gate_m` > 0 ends an episode
once the trunk, having reached the gate's height, drops that far below it (DeepMimic's early termination);
`demo_starts` (starts/demos.py) replaces a share of the fallen starts by states of the planner's rises;
`reward.scales.track` > 0 pays, in those episodes, a per-step tracking term toward the rise the episode started
on (DeepMimic's reference state initialisation and imitation reward; the reference holds at the demonstration's
last state after its end): the seed's pose term toward its joint angles × a Gaussian of the trunk's height error,
with `tracking.end_height_m` > 0 ending the episode once the trunk is that far from the reference's height
(early termination on deviation). The reference reaches the critic only (its height error and pose term), as
HumanUP's; the actor's observation is the same in every episode.
The gate the task carries (critic input, metric `gate`, `success`) latches from its first hold until the trunk
is down: the kneel reached and not lost.
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
from ml_collections import config_dict

from common import events

from training.envs import getup_base, starts
from training.envs.starts import demos as demo_starts
from training.envs import getup_rewards as G


def default_config() -> config_dict.ConfigDict:
    cfg = getup_base.base_config()
    cfg.start_probs = [1.0, 0.0, 0.0]      # (fallen, kneeling, standing): the seed's stage 1 starts fallen
    cfg.reward = config_dict.create(scales=config_dict.create(height=1.0, pose=1.0, gate=0.0, upright=0.0,
                                                              energy=0.0, track=0.0))
    cfg.drop_below_gate_m = 0.0            # [m] below the gate's height after reaching it: the end (0 = never)
    # the tracking term's trunk height tolerance (its Gaussian's σ) and the deviation that ends an episode
    # started on a demonstration (0 = never) [m]
    cfg.tracking = config_dict.create(height_sigma_m=0.1, end_height_m=0.0)
    starts.add_config_groups(cfg, "getup_kneel")   # fallen starts, demonstration starts
    return cfg


class GetupKneel(getup_base.GetupTask):
    """Rise from fallen to the kneel keyframe."""

    def __init__(self, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None,
                 make_env=None):
        super().__init__(config if config is not None else default_config(), config_overrides, make_env)
        if float(self._config.drop_below_gate_m) < 0.0:
            raise ValueError(f"drop_below_gate_m must be >= 0 [m], got {self._config.drop_below_gate_m}")
        self._reference = self._demo_reference() if self._scales["track"] > 0 else None

    def _demo_reference(self) -> dict[str, jax.Array]:
        """The demonstrations' states (`qpos`, each row's demonstration's `last` row) and the pool row of each
        demo-start bank row (`start`): what the tracking term follows."""
        cfg, t = self._config, self._config.tracking
        group = cfg.demo_starts
        if not group.prob > 0:
            raise ValueError("reward.scales.track > 0 follows the demonstration an episode starts on: it needs "
                             "demo_starts.prob > 0")
        if not (t.height_sigma_m > 0 and t.end_height_m >= 0):
            raise ValueError(f"tracking: height_sigma_m must be > 0 and end_height_m >= 0 [m], got "
                             f"{t.height_sigma_m}, {t.end_height_m}")
        if len(self._fallen_banks) != 1:
            raise ValueError("reward.scales.track > 0: the demonstrations must be the task's only start bank")
        args = (str(group.folder), float(group.window_s))
        pool = demo_starts.demo_pool(*args, bool(group.gated_only))
        if abs(float(pool["ctrl_dt"]) - self.dt) > 1e-9:
            raise ValueError(f"demo_starts.folder: its demonstrations step {float(pool['ctrl_dt'])} s, the env "
                             f"{self.dt} s: a reference would run at another speed")
        start = demo_starts.bank_rows(*args, int(group.bank_starts), int(group.seed), bool(group.gated_only))
        return {"qpos": jnp.asarray(pool["qpos"]), "last": jnp.asarray(pool["last"], jnp.int32),
                "start": jnp.asarray(start, jnp.int32)}

    def _task_info(self, info, data) -> dict:
        """The reference's pool row (−1: the episode has none): the start's, then one row per step up to the
        demonstration's last; its trunk height [m] and pose term at this state."""
        if self._reference is None:
            return {}
        ref = self._reference
        if "ref_row" in info:
            now = jnp.maximum(info["ref_row"], 0)
            row = jnp.where(info["ref_row"] >= 0, jnp.minimum(now + 1, ref["last"][now]), -1)
        else:
            row = jnp.where(info["bank_row"] >= 0, ref["start"][jnp.maximum(info["bank_row"], 0)], -1)
        q_ref = ref["qpos"][jnp.maximum(row, 0)]
        on = row >= 0
        return {"ref_row": row, "ref_height_error": jnp.where(on, info["trunk_height"] - q_ref[2], 0.0),
                "ref_pose": jnp.where(on, G.pose_reward(data.qpos[7:], q_ref[7:]), 0.0)}

    def _critic_extras(self, info) -> list[jax.Array]:
        if self._reference is None:
            return []
        return [(info["ref_row"] >= 0).astype(jnp.float32), info["ref_height_error"], info["ref_pose"]]

    def _reward_terms(self, data, info) -> dict[str, jax.Array]:
        return {"height": self.height_orientation(info, self._kneel_targets),
                "pose": G.pose_reward(data.qpos[7:], self._kneel_qpos[7:]),
                "gate": G.gate(info["trunk_height"], info["up_z"]).astype(jnp.float32),
                "upright": G.upright_at_gate_height(info["trunk_height"], info["up"]),
                "energy": self.energy_cost(data), "track": self._tracking(info)}

    def _tracking(self, info) -> jax.Array:
        if self._reference is None:
            return jnp.zeros(())
        err = info["ref_height_error"] / float(self._config.tracking.height_sigma_m)
        return info["ref_pose"] * jnp.exp(-0.5 * jnp.square(err))

    def _gate_state(self, gate_now, was_on, info) -> jax.Array:
        return G.latched_gate(gate_now, was_on, info["trunk_height"])

    def _success(self, info) -> jax.Array:
        return info["gate"]

    def _terminated(self, info) -> jax.Array:
        drop_m = float(self._config.drop_below_gate_m)
        end = super()._terminated(info)
        if drop_m > 0.0:
            end |= info["gate_height_met"] & (info["trunk_height"] < events.KNEEL_GATE_HEIGHT_M - drop_m)
        if self._reference is not None and float(self._config.tracking.end_height_m) > 0.0:
            end |= (info["ref_row"] >= 0) & (jnp.abs(info["ref_height_error"]) > self._config.tracking.end_height_m)
        return end
