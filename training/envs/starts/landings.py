"""The joystick expert rolled until it falls: the mid-fall hand-overs of the knockdown, push-test and wall
banks (knockdown.py, push.py, wall_approach.py) are the first control tick at which the stitched teacher
(training/distill/teacher.py) would hand it to the getup expert, the waist below the 0.5 m switch. Each bank is rolled
once on the host (CPU physics, full-body collision) and cached."""
from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.experts import STUDENT_OBS_KEY, load_expert
from training.envs.starts.bank import frozen_bank

MAX_FALL_S = 3.0   # [s] after the push: a robot still up by then (it caught itself) is left out


def joystick_rollout_env(make_env: Callable, joystick_policy: str, **overrides):
    """The joystick env as the banks roll it (full-body collision, CPU physics, no pushes or noise) and
    `joystick_policy`'s batched action function."""
    env = make_env("joystick", config_overrides={"backend": "cpu", "collision": "full_body", "push.enable": False,
                                                  "noise.level": 0.0, **overrides})
    joystick = load_expert(joystick_policy, "joystick")
    if tuple(map(tuple, env.obs_terms)) != joystick.obs_terms:
        raise ValueError(f"{joystick_policy}: observation terms {joystick.obs_terms} are not the joystick env's")
    return env, jax.jit(jax.vmap(lambda obs: jnp.tanh(joystick.loc(obs))))


def falls(env, act, state, num_ticks: int, armed_tick: np.ndarray, before_step=None):
    """Roll `state` for `num_ticks` control ticks; per start, (qpos, qvel) of the first tick at or after its
    `armed_tick` with the waist below the teacher's switch height, and which starts got there.
    before_step(tick, state) -> state changes the state before a tick's step (a push)."""
    step = jax.jit(jax.vmap(env.step))
    n = len(armed_tick)
    found = np.zeros(n, bool)
    qpos, qvel = np.zeros((n, env.mj_model.nq)), np.zeros((n, env.mj_model.nv))
    for tick in range(num_ticks):
        if before_step is not None:
            state = before_step(tick, state)
        state = step(state, act(state.obs[STUDENT_OBS_KEY]))
        new = ~found & (tick >= armed_tick) & (np.asarray(state.info["waist_height"]) < WAIST_SWITCH_HEIGHT_M)
        qpos[new], qvel[new] = np.asarray(state.data.qpos)[new], np.asarray(state.data.qvel)[new]
        found |= new
    return found, qpos, qvel


def pushed_over(env, act, seed: int, push_tick: np.ndarray, push, none_fell: str) -> tuple[np.ndarray, np.ndarray]:
    """The bank of len(push_tick) seeded standing starts, each pushed by push(tick, state) at its tick: the
    first tick within MAX_FALL_S after it with the waist below the switch height (ValueError none_fell if
    no start got there)."""
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(seed), len(push_tick)))
    found, qpos, qvel = falls(env, act, state, int(push_tick.max() + round(MAX_FALL_S / env.dt)), push_tick, push)
    if not found.any():
        raise ValueError(none_fell)
    return frozen_bank(found, qpos, qvel)


