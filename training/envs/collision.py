"""Collision variants of the ONE robot file (common/models/t1.xml) for MJX, built with MjSpec.

MJX's JAX backend allocates a fixed contact slot for every geom pair that *could* collide (pair count ×
the pair function's contact count) and 4 constraint rows per pyramidal condim-3 contact, whatever the
state. For the full model that is ~300 contacts / ~1200 rows per world and dominates step time and
compile time. Two levers cut it, both applied here, neither changing what the robot can touch:

* robot-robot pairs that can never touch within the joint ranges are excluded (`<exclude>` per body
  pair; every robot body here carries at most one geom). "Can never touch" is measured, not guessed:
  `reachable_body_pairs` poses the robot at many joint configurations uniform within the joint ranges
  and keeps every body pair that comes within `margin` of contact at least once;
* the MJX custom numerics `max_contact_points` (contacts kept per condim group, the deepest ones) and
  `max_geom_pairs` (broad-phase cull per pair-function group) cap the buffers at
  common.model.MJX_NCONMAX contacts → MJX_NJMAX rows. `mjx.make_data`'s naconmax/njmax arguments only
  apply to the warp backend in mujoco-mjx 3.17; the JAX backend reads these numerics instead.

Variants:
* "full_body": every robot geom collides with the floor and with every robot geom it can reach (getup);
* "feet_only": only the two foot boxes collide (with the floor and with each other, which the joystick
  task's `collision` cost reads); Playground's T1 is feet-only too.
"""
from __future__ import annotations

import functools

import mujoco
import numpy as np
from mujoco.mjx._src import collision_driver, constraint

from common import model as t1model

VARIANTS = ("full_body", "feet_only")
FOOT_GEOMS = ("left_foot", "right_foot")

# Self-contact pair search (full_body). Samples: joint configurations uniform within the joint ranges.
# Margin [m]: a pair counts as reachable if it comes this close, so near-misses of the sampling stay in.
PAIR_SEARCH_SAMPLES = 4000
PAIR_SEARCH_MARGIN_M = 0.03
PAIR_SEARCH_SEED = 0


def _robot_geoms(spec: mujoco.MjSpec) -> list:
    return [g for g in spec.geoms if g.parent.name != "world"]


def _sample_contact_bodies(mj: mujoco.MjModel, num_samples: int, margin: float, seed: int) -> set:
    """Body-name pairs of robot-robot contacts (within margin) over random joint configurations."""
    rng = np.random.default_rng(seed)
    data = mujoco.MjData(mj)
    ranges = t1model.joint_ranges(mj)
    robot = t1model.robot_geom_mask(mj)
    mj.geom_margin[robot] = margin
    found = set()
    for _ in range(num_samples):
        data.qpos[:] = mj.qpos0
        data.qpos[2] = 2.0  # lift the robot off the floor: only self-contacts are of interest
        data.qpos[t1model.ROOT_QPOS:] = rng.uniform(ranges[:, 0], ranges[:, 1])
        mujoco.mj_kinematics(mj, data)
        mujoco.mj_collision(mj, data)
        for c in data.contact[:data.ncon]:
            if robot[c.geom1] and robot[c.geom2]:
                b1, b2 = mj.body(mj.geom_bodyid[c.geom1]).name, mj.body(mj.geom_bodyid[c.geom2]).name
                found.add(tuple(sorted((b1, b2))))
    return found


@functools.lru_cache(maxsize=None)
def reachable_body_pairs(num_samples: int = PAIR_SEARCH_SAMPLES, margin: float = PAIR_SEARCH_MARGIN_M,
                         seed: int = PAIR_SEARCH_SEED) -> frozenset:
    """Robot body pairs (sorted names) that come within `margin` of contact somewhere in the joint ranges.

    Seeded and cached: the same pairs in every process. The model's own excludes (shank/foot,
    trunk/shoulder) and MuJoCo's parent-child filter are respected because mj_collision applies them.
    """
    mj = t1model.load_model()
    return frozenset(_sample_contact_bodies(mj, num_samples, margin, seed))


def _candidate_body_pairs(mj: mujoco.MjModel) -> set:
    """Robot body pairs MuJoCo would test (contype/conaffinity, excludes and parent filter applied)."""
    mj_all = t1model.load_model()
    data = mujoco.MjData(mj_all)
    robot = t1model.robot_geom_mask(mj_all)
    mj_all.geom_margin[robot] = 10.0  # everything "touches": enumerates every pair that passes filtering
    data.qpos[:] = mj_all.qpos0
    data.qpos[2] = 20.0
    mujoco.mj_kinematics(mj_all, data)
    mujoco.mj_collision(mj_all, data)
    out = set()
    for c in data.contact[:data.ncon]:
        if robot[c.geom1] and robot[c.geom2]:
            b1, b2 = mj_all.body(mj_all.geom_bodyid[c.geom1]).name, mj_all.body(mj_all.geom_bodyid[c.geom2]).name
            out.add(tuple(sorted((b1, b2))))
    return out


def _add_mjx_caps(spec: mujoco.MjSpec, max_contacts: int, max_geom_pairs: int) -> None:
    """Add the MJX caps as the FIRST custom numerics. mujoco-mjx 3.17 reads a numeric as
    `numeric_data[numeric id]` (not `numeric_data[numeric_adr[id]]`), which is only right while every
    numeric before it has size 1; the model's pd_kp/pd_kd (23 values each) would otherwise be read as
    the caps. So the existing numerics are removed and re-added after the caps."""
    existing = [(n.name, list(n.data)) for n in spec.numerics]
    for n in list(spec.numerics):
        spec.delete(n)
    spec.add_numeric(name="max_contact_points", data=[float(max_contacts)])
    spec.add_numeric(name="max_geom_pairs", data=[float(max_geom_pairs)])
    for name, data in existing:
        spec.add_numeric(name=name, data=data)


@functools.lru_cache(maxsize=None)
def build_model(variant: str, max_contacts: int = t1model.MJX_NCONMAX,
                max_geom_pairs: int = t1model.MJX_NCONMAX) -> mujoco.MjModel:
    """The robot file compiled as one collision variant, with MJX contact caps (cached; treat read-only:
    callers that change options must `copy.copy` it)."""
    return build_spec(variant, max_contacts, max_geom_pairs).compile()


def build_spec(variant: str, max_contacts: int = t1model.MJX_NCONMAX,
               max_geom_pairs: int = t1model.MJX_NCONMAX) -> mujoco.MjSpec:
    """The MjSpec of `build_model` (for backends that add elements before compiling)."""
    if variant not in VARIANTS:
        raise ValueError(f"collision variant {variant!r} unknown; valid: {', '.join(VARIANTS)}")
    spec = t1model.robot_spec()
    if variant == "feet_only":
        for g in _robot_geoms(spec):
            if g.name not in FOOT_GEOMS:
                g.contype, g.conaffinity = 0, 0
    else:
        base = t1model.load_model()
        never = _candidate_body_pairs(base) - set(reachable_body_pairs())
        for b1, b2 in sorted(never):
            spec.add_exclude(bodyname1=b1, bodyname2=b2)
    _add_mjx_caps(spec, max_contacts, max_geom_pairs)
    return spec


def contact_budget(mj: mujoco.MjModel) -> dict:
    """MJX (JAX backend) buffer sizes for one world of `mj`: contacts, constraint rows, geom pairs."""
    dim = collision_driver.make_condim(mj)
    efc_type = constraint.make_efc_type(mj, dim)
    pairs = sum(1 for _ in collision_driver.geom_pairs(mj))
    return {"geom_pairs": pairs, "contacts": int(dim.size), "constraint_rows": int(len(efc_type))}
