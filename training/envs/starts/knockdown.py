"""Knockdown starts: the joystick expert knocked over by a push as hard as the loop's push test, at the first
tick with the waist below the teacher's switch: the getup env replaces a share of its fallen starts with these
mid-fall landings (config knockdown_starts), which it never saw from the settled fallen starts; also
`evaluate --starts knockdown`. Why, with its figures: training/LESSONS.md."""
from __future__ import annotations

import functools
from typing import Callable

import jax.numpy as jnp
import numpy as np
from ml_collections import config_dict

from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.starts.landings import MAX_FALL_S, joystick_rollout_env, pushed_over

# A knockdown: a base speed change [m/s] as hard as the loop's push test (common/push_test.py: 40 N·s ±
# 15 % on the 31.6 kg robot, 1.1–1.5 m/s), the joystick env's pushes being at most 1.0 m/s
KNOCKDOWN_MPS = (1.0, 1.6)
KNOCK_AT_S = (0.3, 1.0)   # [s] after a standing start: the joystick expert is walking or standing by then


def knockdown_config() -> config_dict.ConfigDict:
    """The getup env's knockdown starts: this share of its fallen starts is instead where the teacher hands
    `joystick_policy`, knocked over by a push, to the getup expert mid-fall (from `bank_starts` standing starts,
    seeds from `seed`)."""
    return config_dict.create(prob=0.0, joystick_policy="", bank_starts=256, seed=200_000)


def knockdown_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    return knockdown_bank(env.make_env, group.joystick_policy, int(group.bank_starts), int(group.seed))


@functools.lru_cache(maxsize=4)
def knockdown_bank(make_env: Callable, joystick_policy: str, num_starts: int,
                   seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) where the teacher hands `joystick_policy` (artifact or checkpoint), knocked over from
    `num_starts` seeded standing starts (random commands, half of them zero; full-body collision, CPU
    physics), to the getup expert: the first control tick with the waist below the switch height. Cached
    (read-only arrays): a second env asking for the same bank pays nothing."""
    env, act = joystick_rollout_env(make_env, joystick_policy, zero_command_prob=0.5)
    rng = np.random.default_rng(seed)
    knock_tick = np.round(rng.uniform(*KNOCK_AT_S, num_starts) / env.dt).astype(int)
    heading = rng.uniform(0.0, 2.0 * np.pi, num_starts)
    speed_mps = rng.uniform(*KNOCKDOWN_MPS, num_starts)
    push = jnp.asarray(np.stack([np.cos(heading), np.sin(heading)], 1) * speed_mps[:, None], jnp.float32)

    def knock(tick, state):
        due = jnp.asarray(knock_tick == tick)[:, None]
        return state.replace(data=state.data.replace(qvel=state.data.qvel.at[:, :2].add(jnp.where(due, push, 0.0))))

    return pushed_over(env, act, seed, knock_tick, knock,
                        f"{joystick_policy}: no knockdown of {KNOCKDOWN_MPS} m/s brought the waist below "
                        f"{WAIST_SWITCH_HEIGHT_M} m within {MAX_FALL_S} s in {num_starts} starts")




def landing_bank(make_env: Callable, env, joystick_policy: str, num_starts: int, seed: int):
    return knockdown_bank(make_env, joystick_policy, num_starts, seed)
