"""Domain randomisation as Playground's T1 (mujoco_playground locomotion/t1/randomize.py, Apache-2.0,
DeepMind), restated for this model, as a brax `randomization_fn(mjx_model, rng) -> (model, in_axes)`
(rng: one key per world, shape (num_worlds, 2)).

Per world: floor friction U(0.2, 0.6) (Playground's code; its comment says 0.4–1.0), joint frictionloss
×U(0.9, 1.1), armature ×U(1.0, 1.05), every body mass ×U(0.98, 1.02), trunk mass +U(−1, 1) kg, qpos0
jitter U(−0.05, 0.05) rad, motor kp ×U(0.9, 1.1) (kp lives in actuator_biasprm[:, 0], see base.py).
Not restated: Playground's ankle passive damping ×U(0.5, 2), because this model has no passive joint
damping (kd is the motor's and is sent exactly by the runtime).
"""
from __future__ import annotations

import jax
from mujoco import mjx

FLOOR_GEOM_ID = 0   # the floor is the first geom of common/models/t1.xml
TRUNK_BODY_ID = 1   # the root body
NUM_JOINTS = 23
FLOOR_FRICTION = (0.2, 0.6)
FRICTIONLOSS_SCALE = (0.9, 1.1)
ARMATURE_SCALE = (1.0, 1.05)
BODY_MASS_SCALE = (0.98, 1.02)
TRUNK_MASS_DELTA_KG = (-1.0, 1.0)
QPOS0_JITTER_RAD = (-0.05, 0.05)
KP_SCALE = (0.9, 1.1)
KP_SLOT = 0  # base.KP_SLOT (not imported: base imports heavy modules and this file must stay standalone)

RANDOMIZED_FIELDS = ("geom_friction", "dof_frictionloss", "dof_armature", "body_mass", "qpos0",
                     "actuator_biasprm")


def _one_world(model: mjx.Model, rng: jax.Array):
    k = jax.random.split(rng, 7)

    def u(key, lo_hi, shape=()):
        return jax.random.uniform(key, shape, minval=lo_hi[0], maxval=lo_hi[1])

    friction = model.geom_friction.at[FLOOR_GEOM_ID, 0].set(u(k[0], FLOOR_FRICTION))
    frictionloss = model.dof_frictionloss.at[6:].multiply(u(k[1], FRICTIONLOSS_SCALE, (NUM_JOINTS,)))
    armature = model.dof_armature.at[6:].multiply(u(k[2], ARMATURE_SCALE, (NUM_JOINTS,)))
    mass = model.body_mass * u(k[3], BODY_MASS_SCALE, (model.nbody,))
    mass = mass.at[TRUNK_BODY_ID].add(u(k[4], TRUNK_MASS_DELTA_KG))
    qpos0 = model.qpos0.at[7:].add(u(k[5], QPOS0_JITTER_RAD, (NUM_JOINTS,)))
    biasprm = model.actuator_biasprm.at[:, KP_SLOT].multiply(u(k[6], KP_SCALE, (model.nu,)))
    return friction, frictionloss, armature, mass, qpos0, biasprm


def domain_randomize(model: mjx.Model, rng: jax.Array):
    """Per-world randomised model and its vmap in_axes (brax / Playground wrapper convention)."""
    values = jax.vmap(_one_world, in_axes=(None, 0))(model, rng)
    fields = dict(zip(RANDOMIZED_FIELDS, values))
    in_axes = jax.tree_util.tree_map(lambda _: None, model)
    in_axes = in_axes.tree_replace({f: 0 for f in RANDOMIZED_FIELDS})
    return model.tree_replace(fields), in_axes
