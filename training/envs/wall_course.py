"""The seed's low-wall course in the training worlds (ours: the seed trains on flat ground only).

Why: in the loop's wall test (sim_hil/eval, Tables 6.1–6.2) the robot trips over a 0.2 m wall and must get
up beside it, on it or with its legs across it. A getup expert that has only risen on open floor costs
the student several getup attempts at each wall (training/LESSONS.md). With the course in the world, the
getup evaluation can start from where the joystick expert lands after walking into a wall (handover.wall_bank,
`evaluate --starts wall`) and the unified env can walk a share of its episodes into one (config walls.prob).

The course is sim_hil's (common/scenarios.py add_low_walls: three walls 6 m apart, the same geoms the
evaluation builds), moved along +x to config.wall_course.first_wall_x_m (30 m): every other start lies
within a few metres of the origin, so the walls change nothing there. An approach (course_start) is a
standing start approach_m before the first wall (config; APPROACH_M by default), facing it within
±APPROACH_YAW_RAD, walking at a constant forward command as the loop's test does (0.4 m/s there).
"""
from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
from ml_collections import config_dict

from common import scenarios

FIRST_WALL_X_M = 30.0               # the training course's first wall [m]; the evaluation's is at 2 m
APPROACH_M = (0.3, 2.5)             # default approach_m: start this far before the first wall's centre plane [m]
APPROACH_LATERAL_M = 3.0            # |y| of the start [m] (the walls are 40 m long)
APPROACH_YAW_RAD = 0.3              # heading off +x [rad]
APPROACH_SPEED_MPS = (0.3, 0.6)     # forward command [m/s], held for the episode (the loop's test: 0.4)


def config() -> config_dict.ConfigDict:
    """enable: the course is in the world (tasks whose wall share is > 0 add it on their own). approach_m: a
    longer run-up meets the wall at walking speed, as the loop's test meets its second and third walls."""
    return config_dict.create(enable=False, first_wall_x_m=FIRST_WALL_X_M, approach_m=list(APPROACH_M))


def add_to_spec(spec: mujoco.MjSpec, cfg: config_dict.ConfigDict) -> None:
    scenarios.add_low_walls(spec, float(cfg.first_wall_x_m))


def course_start(rng: jax.Array, cfg: config_dict.ConfigDict) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(xy [m], yaw [rad], command (vx, vy, yaw rate)) of one approach to the first wall."""
    k_x, k_y, k_yaw, k_v = jax.random.split(rng, 4)
    near_m, far_m = cfg.approach_m
    if not 0.0 <= near_m <= far_m:
        raise ValueError(f"wall_course.approach_m must be an ordered pair of distances [m] >= 0, got {near_m, far_m}")
    x = cfg.first_wall_x_m - jax.random.uniform(k_x, minval=near_m, maxval=far_m)
    y = jax.random.uniform(k_y, minval=-APPROACH_LATERAL_M, maxval=APPROACH_LATERAL_M)
    yaw = jax.random.uniform(k_yaw, minval=-APPROACH_YAW_RAD, maxval=APPROACH_YAW_RAD)
    speed = jax.random.uniform(k_v, minval=APPROACH_SPEED_MPS[0], maxval=APPROACH_SPEED_MPS[1])
    return jnp.stack([x, y]), yaw, jnp.stack([speed, 0.0, 0.0])


def credited_progress(best_x: jax.Array, credit_x: jax.Array, x: jax.Array, speed_cap_mps: jax.Array,
                      dt: float) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(best_x, credit_x, gained [m]) after one step at base x [m]: new ground along +x is banked (best_x, the
    furthest x so far) and paid out at no more than speed_cap_mps (the held command), so a fall forward across
    a wall keeps paying while the robot gets up beyond it, standing still pays nothing, and neither walking
    faster than commanded nor stepping back and forth earns more."""
    best_x = jnp.maximum(best_x, x)
    new_credit = jnp.minimum(best_x, credit_x + jnp.maximum(speed_cap_mps, 0.0) * dt)
    return best_x, new_credit, new_credit - credit_x   # ≥ 0: credit_x never passes best_x
