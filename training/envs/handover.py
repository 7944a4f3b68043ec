"""Hand-over starts: the states in which the stitched teacher hands a robot from one expert to the other.

The teacher (training/teacher.py) switches from the getup expert to the joystick expert when the waist
rises past WAIST_SWITCH_HEIGHT_M (0.5 m). The joystick expert was trained from standing starts only, and the
getup expert arrives there mid-lunge: with the keyframe expert, trunk at 0.62 m rising at 0.8 m/s (median)
in the hand-overs it holds, at 1.25 m/s in the 32 % it drops within 3 s
(training/runs/joystick_handover/PROGRESS.md). Fine-tuning the joystick expert from these states teaches it
to catch the lunge (ours, not the seed's: the seed's teacher stitches two experts as trained).

`handover_bank` rolls a getup artifact from fallen starts in the getup env (full-body collision, CPU
physics: a one-off host computation, whatever backend trains) and keeps, per episode, the state of the
first control tick with the waist at or above the switch height, with the joint targets [rad] of the getup
expert's last action (the joystick expert's last action at the hand-over, in its own map). The joystick env
(training/envs/joystick.py, config.handover) starts a share of its episodes from it, each turned to a
random heading and moved to a random place as its standing starts are.

`knockdown_bank` is the other way: the joystick expert, standing or walking, is knocked over by a push as
hard as the loop's push test, and the state of the first control tick with the waist below the switch
height is where the getup expert takes over, mid-fall. The getup expert was trained from fallen starts after
the runtime's PREPARE ramp (limbs straightened, at rest), so a push's landing, limbs in a walking pose and
still moving, was new to it: in the loop's push test the failed getup attempts after one forward fall are
what misses the seed's 1.16 (training/runs/student_knockdown/PROGRESS.md). The getup env (config
knockdown_starts) replaces a share of its fallen starts with these.
"""
from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from brax import math as brax_math

from training import observation as obsdef
from training.teacher import STUDENT_OBS_KEY, WAIST_SWITCH_HEIGHT_M, load_expert

MAX_RISE_S = 10.0   # [s] a fallen start that has not handed over by then is left out
# A knockdown: a base speed change [m/s] as hard as the loop's push test (sim_hil/eval/plans.py: 40 N·s ±
# 15 % on the 31.6 kg robot, 1.1–1.5 m/s), the joystick env's pushes being at most 1.0 m/s
KNOCKDOWN_MPS = (1.0, 1.6)
KNOCK_AT_S = (0.3, 1.0)       # [s] after a standing start: the joystick expert is walking or standing by then
MAX_FALL_S = 3.0              # [s] after the push: a robot still up by then (it caught itself) is left out


class HandoverBank(NamedTuple):
    qpos: np.ndarray            # (n, nq)
    qvel: np.ndarray            # (n, nv); the free joint's linear part in world axes [m/s]
    joint_targets: np.ndarray   # (n, 23) the getup expert's last joint targets [rad]


def handover_bank(getup_policy: str, num_starts: int, seed: int) -> HandoverBank:
    """Hand-over states of `getup_policy` (artifact or checkpoint) from `num_starts` random draws of a bank of
    `num_starts` seeded fallen starts (seed, seed + 1, …); identical states (a start drawn twice) kept once."""
    from training import envs
    env = envs.make("getup", config_overrides={"backend": "cpu", "start_probs": [1.0, 0.0, 0.0],
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


@functools.lru_cache(maxsize=4)
def knockdown_bank(joystick_policy: str, num_starts: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) where the teacher hands `joystick_policy` (artifact or checkpoint), knocked over from
    `num_starts` seeded standing starts (random commands, half of them zero; full-body collision, CPU
    physics), to the getup expert: the first control tick with the waist below the switch height. Cached
    (read-only arrays): a second env asking for the same bank pays nothing."""
    from training import envs
    env = envs.make("joystick", config_overrides={"backend": "cpu", "collision": "full_body", "push.enable": False,
                                                  "zero_command_prob": 0.5, "noise.level": 0.0})
    joystick = load_expert(joystick_policy, "joystick")
    if tuple(map(tuple, env.obs_terms)) != joystick.obs_terms:
        raise ValueError(f"{joystick_policy}: observation terms {joystick.obs_terms} are not the joystick env's")
    rng = np.random.default_rng(seed)
    knock_tick = np.round(rng.uniform(*KNOCK_AT_S, num_starts) / env.dt).astype(int)
    heading = rng.uniform(0.0, 2.0 * np.pi, num_starts)
    push = np.stack([np.cos(heading), np.sin(heading)], 1) * rng.uniform(*KNOCKDOWN_MPS, num_starts)[:, None]
    act = jax.jit(jax.vmap(lambda obs: jnp.tanh(joystick.loc(obs))))
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(seed), num_starts))
    found = np.zeros(num_starts, bool)
    qpos, qvel = np.zeros((num_starts, env.mj_model.nq)), np.zeros((num_starts, env.mj_model.nv))
    for tick in range(int(knock_tick.max() + round(MAX_FALL_S / env.dt))):
        due = jnp.asarray(knock_tick == tick)[:, None]
        state = state.replace(data=state.data.replace(
            qvel=state.data.qvel.at[:, :2].add(jnp.where(due, jnp.asarray(push, jnp.float32), 0.0))))
        state = step(state, act(state.obs[STUDENT_OBS_KEY]))
        new = ~found & (tick >= knock_tick) & (np.asarray(state.info["waist_height"]) < WAIST_SWITCH_HEIGHT_M)
        qpos[new], qvel[new] = np.asarray(state.data.qpos)[new], np.asarray(state.data.qvel)[new]
        found |= new
    if not found.any():
        raise ValueError(f"{joystick_policy}: no knockdown of {KNOCKDOWN_MPS} m/s brought the waist below "
                         f"{WAIST_SWITCH_HEIGHT_M} m within {MAX_FALL_S} s in {num_starts} starts")
    bank = qpos[found].astype(np.float32), qvel[found].astype(np.float32)
    for array in bank:
        array.flags.writeable = False
    return bank


def place(qpos, qvel, xy, yaw):
    """A free-floating robot's state moved to `xy` [m] and turned by `yaw` [rad] about the world z axis:
    the root orientation and the world-frame linear velocity turn; the body-frame angular velocity and the
    joints do not."""
    turn = brax_math.quat_rot_axis(jnp.array([0.0, 0.0, 1.0]), yaw)     # (w, x, y, z), as MuJoCo's
    qpos = qpos.at[0:2].set(xy).at[3:7].set(brax_math.quat_mul(turn, qpos[3:7]))
    return qpos, qvel.at[0:3].set(brax_math.rotate(qvel[0:3], turn))
