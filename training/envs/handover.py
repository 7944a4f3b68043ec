"""Hand-over starts: the states in which the stitched teacher (training/teacher.py: getup expert below the
waist's 0.5 m switch, joystick expert above) hands a robot from one expert to the other; ours, not the seed's.
Each bank is rolled once on the host (CPU physics, full-body collision) when an env is built.

* `handover_bank`: a getup artifact rising from fallen starts, at the first tick with the waist at the switch,
  with its last joint targets: the joystick env starts a share of episodes there (config.handover), so the
  joystick expert learns to catch the lunge it is handed.
* `knockdown_bank`: the joystick expert knocked over by a push as hard as the loop's push test, at the first
  tick with the waist below the switch: the getup env replaces a share of its fallen starts with these mid-fall
  landings (config knockdown_starts), which it never saw from the settled fallen starts.
* `push_test_bank`: the loop's push test itself (common/push_test.py), a force on the Trunk over one physics
  step; only the shove's own landings reproduce the loop's forward-push attempts.
* `wall_bank`: the hand-over after the joystick expert walked into the low-wall course (`evaluate --starts
  wall`).
Why each exists, with its figures: training/LESSONS.md.
"""
from __future__ import annotations

import functools
import math
from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from brax import math as brax_math
from ml_collections import config_dict

from common.events import heading_from_quat
from common import push_test
from common.scenarios import TORSO_BODY
from common import observation as obsdef
from training.envs import start_banks, wall_course
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.experts import STUDENT_OBS_KEY, load_expert

MAX_RISE_S = 10.0   # [s] a fallen start that has not handed over by then is left out
# A knockdown: a base speed change [m/s] as hard as the loop's push test (common/push_test.py: 40 N·s ±
# 15 % on the 31.6 kg robot, 1.1–1.5 m/s), the joystick env's pushes being at most 1.0 m/s
KNOCKDOWN_MPS = (1.0, 1.6)
KNOCK_AT_S = (0.3, 1.0)       # [s] after a standing start: the joystick expert is walking or standing by then
MAX_FALL_S = 3.0              # [s] after the push: a robot still up by then (it caught itself) is left out
# A wall approach: the command is held (the joystick env resamples it after 10 s) while the robot walks
# up to 2.5 m at ≥ 0.3 m/s (wall_course.APPROACH_*) and falls; one still up by then stepped over or stood
MAX_WALL_WALK_S = 9.5


class HandoverBank(NamedTuple):
    qpos: np.ndarray            # (n, nq)
    qvel: np.ndarray            # (n, nv); the free joint's linear part in world axes [m/s]
    joint_targets: np.ndarray   # (n, 23) the getup expert's last joint targets [rad]


def handover_bank(make_env: Callable, getup_policy: str, num_starts: int, seed: int) -> HandoverBank:
    """Hand-over states of `getup_policy` (artifact or checkpoint) from `num_starts` random draws of a bank of
    `num_starts` seeded fallen starts (seed, seed + 1, …); identical states (a start drawn twice) kept once."""
    env = make_env("getup", config_overrides={"backend": "cpu", "start_probs": [1.0, 0.0, 0.0],
                                               "fallen_bank_size": int(num_starts), "fallen_seed": int(seed),
                                               "obs_noise_scale": 0.0})
    getup = load_expert(getup_policy, "getup")
    if tuple(map(tuple, env.obs_terms)) != getup.obs_terms:
        raise ValueError(f"{getup_policy}: observation terms {getup.obs_terms} are not the getup env's")
    default_pose = jnp.asarray(env.manifest_fields()["default_pose"], jnp.float32)

    def act(state):
        action = jnp.tanh(getup.loc(state.obs[STUDENT_OBS_KEY]))
        return action, obsdef.action_to_targets(default_pose, jnp.asarray(getup.action_scale), action)

    reset, step, act = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step)), jax.jit(jax.vmap(act))
    state = reset(jax.random.split(jax.random.PRNGKey(seed), num_starts))
    found = np.zeros(num_starts, bool)
    qpos = np.zeros((num_starts, env.mj_model.nq))
    qvel = np.zeros((num_starts, env.mj_model.nv))
    targets = np.zeros((num_starts, getup.action_scale.shape[0]))
    for _ in range(int(round(MAX_RISE_S / env.dt))):
        action, target = act(state)
        state = step(state, action)
        new = ~found & (np.asarray(state.info["waist_height"]) >= WAIST_SWITCH_HEIGHT_M)
        qpos[new], qvel[new], targets[new] = (np.asarray(state.data.qpos)[new], np.asarray(state.data.qvel)[new],
                                              np.asarray(target)[new])
        found |= new
        if found.all():
            break
    if not found.any():
        raise ValueError(f"{getup_policy}: no hand-over in {MAX_RISE_S} s from {num_starts} fallen starts "
                         f"(the waist never reached {WAIST_SWITCH_HEIGHT_M} m): not a trained getup expert")
    _, keep = np.unique(qpos[found].round(9), axis=0, return_index=True)
    keep = np.sort(keep)
    return HandoverBank(qpos[found][keep].astype(np.float32), qvel[found][keep].astype(np.float32),
                        targets[found][keep].astype(np.float32))


def _joystick_rollout_env(make_env: Callable, joystick_policy: str, **overrides):
    """The joystick env as the banks roll it (full-body collision, CPU physics, no pushes or noise) and
    `joystick_policy`'s batched action function."""
    env = make_env("joystick", config_overrides={"backend": "cpu", "collision": "full_body", "push.enable": False,
                                                  "noise.level": 0.0, **overrides})
    joystick = load_expert(joystick_policy, "joystick")
    if tuple(map(tuple, env.obs_terms)) != joystick.obs_terms:
        raise ValueError(f"{joystick_policy}: observation terms {joystick.obs_terms} are not the joystick env's")
    return env, jax.jit(jax.vmap(lambda obs: jnp.tanh(joystick.loc(obs))))


def _falls(env, act, state, num_ticks: int, armed_tick: np.ndarray, before_step=None):
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


def _pushed_over(env, act, seed: int, push_tick: np.ndarray, push, none_fell: str) -> tuple[np.ndarray, np.ndarray]:
    """The bank of len(push_tick) seeded standing starts, each pushed by push(tick, state) at its tick: the
    first tick within MAX_FALL_S after it with the waist below the switch height (ValueError none_fell if
    no start got there)."""
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(seed), len(push_tick)))
    found, qpos, qvel = _falls(env, act, state, int(push_tick.max() + round(MAX_FALL_S / env.dt)), push_tick, push)
    if not found.any():
        raise ValueError(none_fell)
    return start_banks.frozen_bank(found, qpos, qvel)


def handover_config() -> config_dict.ConfigDict:
    """The joystick env's hand-over starts: this share of episodes starts where the stitched teacher hands the
    getup expert `getup_policy`'s rise over, from `bank_starts` fallen starts (seeds from `seed`, apart from the
    evaluations' 0 …); 0 = standing starts only, as Playground's."""
    return config_dict.create(prob=0.0, getup_policy="", bank_starts=256, seed=100_000)


def knockdown_config() -> config_dict.ConfigDict:
    """The getup env's knockdown starts: this share of its fallen starts is instead where the teacher hands
    `joystick_policy`, knocked over by a push, to the getup expert mid-fall (from `bank_starts` standing starts,
    seeds from `seed`)."""
    return config_dict.create(prob=0.0, joystick_policy="", bank_starts=256, seed=200_000)


def knockdown_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    return knockdown_bank(env.make_env, group.joystick_policy, int(group.bank_starts), int(group.seed))


@functools.lru_cache(maxsize=4)
def knockdown_bank(make_env: Callable, joystick_policy: str, num_starts: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) where the teacher hands `joystick_policy` (artifact or checkpoint), knocked over from
    `num_starts` seeded standing starts (random commands, half of them zero; full-body collision, CPU
    physics), to the getup expert: the first control tick with the waist below the switch height. Cached
    (read-only arrays): a second env asking for the same bank pays nothing."""
    env, act = _joystick_rollout_env(make_env, joystick_policy, zero_command_prob=0.5)
    rng = np.random.default_rng(seed)
    knock_tick = np.round(rng.uniform(*KNOCK_AT_S, num_starts) / env.dt).astype(int)
    heading = rng.uniform(0.0, 2.0 * np.pi, num_starts)
    push = jnp.asarray(np.stack([np.cos(heading), np.sin(heading)], 1) * rng.uniform(*KNOCKDOWN_MPS, num_starts)[:, None],
                       jnp.float32)

    def knock(tick, state):
        due = jnp.asarray(knock_tick == tick)[:, None]
        return state.replace(data=state.data.replace(qvel=state.data.qvel.at[:, :2].add(jnp.where(due, push, 0.0))))

    return _pushed_over(env, act, seed, knock_tick, knock,
                        f"{joystick_policy}: no knockdown of {KNOCKDOWN_MPS} m/s brought the waist below "
                        f"{WAIST_SWITCH_HEIGHT_M} m within {MAX_FALL_S} s in {num_starts} starts")


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
def push_test_bank(make_env: Callable, joystick_policy: str, num_starts: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) where the teacher hands `joystick_policy` over to the getup expert in the loop's push test
    (module docstring) from `num_starts` seeded standing starts: start i is shoved as the test's trial i of
    seed `seed + i` (push_test.push_draw), relative to the robot's heading then; the first control tick with the
    waist below the switch height. Shoves it caught are left out. Cached as knockdown_bank."""
    env, act = _joystick_rollout_env(make_env, joystick_policy, zero_command_prob=1.0)
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

    return _pushed_over(env, act, seed, push_tick, shove,
                        f"{joystick_policy}: the push test's torso shoves brought the waist below "
                        f"{WAIST_SWITCH_HEIGHT_M} m within {MAX_FALL_S} s in none of {num_starts} standing starts")


@functools.lru_cache(maxsize=4)
def wall_bank(make_env: Callable, joystick_policy: str, num_starts: int, seed: int,
              first_wall_x_m: float = wall_course.FIRST_WALL_X_M) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) where the teacher hands `joystick_policy` over to the getup expert after it walked into
    the low-wall course (wall_course.py; first wall at `first_wall_x_m`) from `num_starts` seeded approaches
    (wall_course.course_start): the first control tick with the waist below the switch height. Approaches
    where it stepped over the wall or stood are left out. Positions are in the course's world frame: a
    getup env draws them with its course at the same x. Cached as knockdown_bank."""
    env, act = _joystick_rollout_env(make_env, joystick_policy, **{"wall_course.enable": True,
                                                         "wall_course.first_wall_x_m": float(first_wall_x_m)})
    keys = jax.random.split(jax.random.PRNGKey(seed), 2 * num_starts)
    state = jax.jit(jax.vmap(env.reset))(keys[:num_starts])
    xy, yaw, command = jax.vmap(lambda k: wall_course.course_start(k, env.config.wall_course))(keys[num_starts:])
    upright = state.data.qpos.at[:, 3:7].set(jnp.array([1.0, 0.0, 0.0, 0.0]))   # place() turns from heading 0
    qpos, qvel = jax.vmap(place)(upright, state.data.qvel, xy, yaw)
    state = state.replace(data=state.data.replace(qpos=qpos, qvel=qvel), info={**state.info, "command": command})
    found, qpos, qvel = _falls(env, act, state, int(round(MAX_WALL_WALK_S / env.dt)), np.zeros(num_starts, int))
    if not found.any():
        raise ValueError(f"{joystick_policy}: walking into the low walls brought the waist below "
                         f"{WAIST_SWITCH_HEIGHT_M} m within {MAX_WALL_WALK_S} s in none of {num_starts} approaches")
    return start_banks.frozen_bank(found, qpos, qvel)


def place(qpos, qvel, xy, yaw):
    """A free-floating robot's state moved to `xy` [m] and turned by `yaw` [rad] about the world z axis:
    the root orientation and the world-frame linear velocity turn; the body-frame angular velocity and the
    joints do not."""
    turn = brax_math.quat_rot_axis(jnp.array([0.0, 0.0, 1.0]), yaw)     # (w, x, y, z), as MuJoCo's
    qpos = qpos.at[0:2].set(xy).at[3:7].set(brax_math.quat_mul(turn, qpos[3:7]))
    return qpos, qvel.at[0:3].set(brax_math.rotate(qvel[0:3], turn))
