"""The assist stage of the getup tasks: a training aid of ours, not the seed's, a change of the model (so both
physics backends get it with no code of their own), off by default, and a policy trained with it is never
exported as trained (`assisted`, used by export.exported_as_trained).

The elastic harness (config.harness): a spatial tendon from a world site above the start (x = y = 0, where stage
2's kneel starts; `anchor_height_m`) to a trunk site `attach_above_trunk_m` above the trunk origin. Its spring is
slack while the trunk is at or above `slack_trunk_height_m` (the standing torso height) and pulls with stiffness ×
(how far below) [N] when the trunk is lower: × 0.26 m at the kneel. At stiffness 0 the model has no harness.

Why: at full gravity (and at half: LESSONS), PPO from the kneel never found a way up: every exploratory move that
tips the robot ends a stage-2 episode, so the policy learned to hold the kneel. The harness carries part of the weight where it is heaviest and, attached above the centre of
mass, holds the robot like a pendulum (attached at the trunk origin it tipped even a held kneel over:
measured), so leg motions that rise are tried without falling (with targets at home from the kneel, no
harness: the robot falls; 1100 N/m: it rises to standing height). Later
stages lower the stiffness to 0 by fine-tuning `--from` the previous one (HoST, Huang et al. 2025, also
pulls the base up early in training).
"""
from __future__ import annotations

import mujoco

TENDON = "harness"
ANCHOR_SITE, TRUNK_SITE = "harness_anchor", "harness_trunk"
TRUNK_BODY = "Trunk"


def stiffness(cfg) -> float:
    """The config's harness stiffness [N/m] (0 where a task has no harness), checked."""
    k = float(cfg.get("harness", {}).get("stiffness_n_per_m", 0.0))
    if k < 0.0:
        raise ValueError(f"harness.stiffness_n_per_m {k}: must be >= 0 (0 = no harness)")
    return k


def assisted(cfg) -> bool:
    """Whether an env config trains with an assist (a policy from it is only a start for the next stage)."""
    return stiffness(cfg) != 0.0


def add_harness(spec: mujoco.MjSpec, cfg) -> None:
    """Add the harness of cfg.harness to the robot's spec (nothing when its stiffness is 0)."""
    k = stiffness(cfg)
    if k == 0.0:
        return
    h = cfg.harness
    slack_length = h.anchor_height_m - h.slack_trunk_height_m - h.attach_above_trunk_m   # [m]
    if h.slack_trunk_height_m <= 0.0 or slack_length <= 0.0:
        raise ValueError(f"harness: need 0 < slack_trunk_height_m ({h.slack_trunk_height_m}) and its attachment "
                         f"(+{h.attach_above_trunk_m}) below anchor_height_m ({h.anchor_height_m})")
    spec.worldbody.add_site(name=ANCHOR_SITE, pos=[0.0, 0.0, h.anchor_height_m])
    spec.body(TRUNK_BODY).add_site(name=TRUNK_SITE, pos=[0.0, 0.0, h.attach_above_trunk_m])
    # springlength (low, high): no force while low ≤ length ≤ high, so the rope pulls and never pushes
    tendon = spec.add_tendon(name=TENDON, stiffness=k, springlength=[0.0, slack_length])
    tendon.wrap_site(ANCHOR_SITE)
    tendon.wrap_site(TRUNK_SITE)
