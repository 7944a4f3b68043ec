"""Push-test starts: the loop's push test itself (common/push_test.py), a force on the Trunk over one physics
step, delivered to the joystick expert standing; the first tick with the waist below the teacher's switch
(`evaluate --starts push`): only the shove's own landings reproduce the loop's forward-push attempts. The
unified env's torso knockdowns draw the same shove in JAX (TorsoShove)."""
from __future__ import annotations

import functools
import math
from typing import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from common import push_test
from common.events import heading_from_quat
from common.scenarios import TORSO_BODY
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.starts.bank import place
from training.envs.starts.landings import MAX_FALL_S, joystick_rollout_env, pushed_over


def torso_impulse_dqvel(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray,
                        impulse_ns: np.ndarray) -> np.ndarray:
    """The change of qvel [nv] that a world-frame impulse [N·s] on the Trunk's centre of mass makes at `qpos`:
    M⁻¹ Jᵀ impulse. sim_hil delivers a push as the force impulse / dt on the Trunk over one physics step
    (sim_hil/sim.py _trunk_force), the same up to what the contacts take in that step."""
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    jacp = np.zeros((3, model.nv))
    mujoco.mj_jacBodyCom(model, data, jacp, None, model.body(TORSO_BODY).id)
    dqvel = np.zeros((1, model.nv))
    mujoco.mj_solveM(model, data, dqvel, (jacp.T @ impulse_ns).reshape(1, -1))
    return dqvel[0]


def torso_shove_response(model: mujoco.MjModel, home_qpos: np.ndarray) -> np.ndarray:
    """(2, nv): the change of qvel per N·s of torso impulse along the robot's x and y, standing in `home_qpos`
    (heading +x). TorsoShove turns it to the robot's heading (free joint: linear part in world
    axes, angular part in the body's): exact for a robot standing upright, close for one walking."""
    data = mujoco.MjData(model)
    return np.stack([torso_impulse_dqvel(model, data, home_qpos, axis) for axis in np.eye(3)[:2]])


class TorsoShove:
    """The loop's push-test shove drawn in JAX (push_test.push_draw's distribution: forward or backward 2 : 1
    off the heading, impulse and angle spread as the test's), as the change of qvel it makes: the unified
    env's torso knockdowns use it."""

    def __init__(self, model: mujoco.MjModel, home_qpos: np.ndarray):
        self._impulse_ns, self._impulse_spread = push_test.PUSH_IMPULSE_NS, push_test.PUSH_IMPULSE_SPREAD
        self._angle_spread_rad = push_test.PUSH_ANGLE_SPREAD_RAD
        self._response = jnp.asarray(torso_shove_response(model, np.asarray(home_qpos)))

    def dqvel(self, qpos: jax.Array, rng: jax.Array) -> jax.Array:
        """Δqvel [nv] of one shove of the robot at `qpos`, turned to its heading."""
        k_back, k_size, k_angle = jax.random.split(rng, 3)
        backward = jax.random.bernoulli(k_back, 1.0 / 3.0)   # F F B, as the test
        spread = self._impulse_spread
        impulse = self._impulse_ns * (1.0 + jax.random.uniform(k_size, minval=-spread, maxval=spread))
        angle = (jax.random.uniform(k_angle, minval=-self._angle_spread_rad, maxval=self._angle_spread_rad)
                 + jnp.pi * backward)
        local = impulse * (jnp.cos(angle) * self._response[0] + jnp.sin(angle) * self._response[1])
        w, x, y, z = qpos[3], qpos[4], qpos[5], qpos[6]
        heading = jnp.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        return place(jnp.zeros_like(qpos), local, qpos[0:2], heading)[1]   # turns only the linear part


@functools.lru_cache(maxsize=4)
def push_test_bank(make_env: Callable, joystick_policy: str, num_starts: int,
                   seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) where the teacher hands `joystick_policy` over to the getup expert in the loop's push test
    (this module's docstring) from `num_starts` seeded standing starts: start i is shoved as the test's trial i of
    seed `seed + i` (push_test.push_draw), relative to the robot's heading then; the first control tick with the
    waist below the switch height. Shoves it caught are left out. Cached (read-only arrays)."""
    env, act = joystick_rollout_env(make_env, joystick_policy, zero_command_prob=1.0)
    draws = [push_test.push_draw(i, seed + i) for i in range(num_starts)]
    push_tick = np.array([round(d.at_s / env.dt) for d in draws])
    model = env.mj_model
    scratch = mujoco.MjData(model)

    def shove(tick, state):
        due = np.flatnonzero(push_tick == tick)
        if due.size == 0:
            return state
        qpos, qvel = np.asarray(state.data.qpos), np.array(state.data.qvel)
        for i in due:
            angle = heading_from_quat(qpos[i, 3:7]) + draws[i].angle_rad
            impulse = draws[i].impulse_ns * np.array([math.cos(angle), math.sin(angle), 0.0])
            qvel[i] += torso_impulse_dqvel(model, scratch, qpos[i], impulse)
        return state.replace(data=state.data.replace(qvel=jnp.asarray(qvel, state.data.qvel.dtype)))

    return pushed_over(env, act, seed, push_tick, shove,
                        f"{joystick_policy}: the push test's torso shoves brought the waist below "
                        f"{WAIST_SWITCH_HEIGHT_M} m within {MAX_FALL_S} s in none of {num_starts} standing starts")



def landing_bank(make_env: Callable, env, joystick_policy: str, num_starts: int, seed: int):
    return push_test_bank(make_env, joystick_policy, num_starts, seed)
