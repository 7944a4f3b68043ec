"""Wall-approach starts: the unified env's share of episodes that walk into the low-wall course
(training/envs/wall_course.py) at a held forward command (config walls), and the hand-over after the joystick
expert walked into it and fell (`evaluate --starts wall`)."""
from __future__ import annotations

import functools
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from ml_collections import config_dict

from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs import wall_course
from training.envs.starts.bank import frozen_bank, place
from training.envs.starts.landings import falls, joystick_rollout_env

# The command is held (the joystick env resamples it after 10 s) while the robot walks up to 2.5 m at
# ≥ 0.3 m/s (wall_course.APPROACH_*) and falls; one still up by then stepped over or stood
MAX_WALL_WALK_S = 9.5


def walls_config() -> config_dict.ConfigDict:
    """The unified env's share of episodes that start before the course's first wall (wall_course.course_start)."""
    return config_dict.create(prob=0.0)


@functools.lru_cache(maxsize=4)
def wall_bank(make_env: Callable, joystick_policy: str, num_starts: int, seed: int,
              first_wall_x_m: float = wall_course.FIRST_WALL_X_M) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) where the teacher hands `joystick_policy` over to the getup expert after it walked into
    the low-wall course (wall_course.py; first wall at `first_wall_x_m`) from `num_starts` seeded approaches
    (wall_course.course_start): the first control tick with the waist below the switch height. Approaches
    where it stepped over the wall or stood are left out. Positions are in the course's world frame: a
    getup env draws them with its course at the same x. Cached (read-only arrays)."""
    env, act = joystick_rollout_env(make_env, joystick_policy, **{"wall_course.enable": True,
                                                         "wall_course.first_wall_x_m": float(first_wall_x_m)})
    keys = jax.random.split(jax.random.PRNGKey(seed), 2 * num_starts)
    state = jax.jit(jax.vmap(env.reset))(keys[:num_starts])
    xy, yaw, command = jax.vmap(lambda k: wall_course.course_start(k, env.config.wall_course))(keys[num_starts:])
    upright = state.data.qpos.at[:, 3:7].set(jnp.array([1.0, 0.0, 0.0, 0.0]))   # place() turns from heading 0
    qpos, qvel = jax.vmap(place)(upright, state.data.qvel, xy, yaw)
    state = state.replace(data=state.data.replace(qpos=qpos, qvel=qvel), info={**state.info, "command": command})
    found, qpos, qvel = falls(env, act, state, int(round(MAX_WALL_WALK_S / env.dt)), np.zeros(num_starts, int))
    if not found.any():
        raise ValueError(f"{joystick_policy}: walking into the low walls brought the waist below "
                         f"{WAIST_SWITCH_HEIGHT_M} m within {MAX_WALL_WALK_S} s in none of {num_starts} approaches")
    return frozen_bank(found, qpos, qvel)



def landing_bank(make_env: Callable, env, joystick_policy: str, num_starts: int, seed: int):
    return wall_bank(make_env, joystick_policy, num_starts, seed, float(env.config.wall_course.first_wall_x_m))
