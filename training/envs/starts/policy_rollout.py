"""The states where a policy's rollouts first meet a hand-over condition: the banks that start one expert where
another hands over to it (handover.py: the getup expert's rise at the waist switch; rolled.py: the roll's
hand-over to the face-down rise). Rolled once on the host (CPU physics) when the env is built."""
from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from common import observation as obsdef
from training.envs.experts import STUDENT_OBS_KEY, load_expert


class HandoverStates(NamedTuple):
    qpos: np.ndarray            # (n, nq)
    qvel: np.ndarray            # (n, nv); the free joint's linear part in world axes [m/s]
    joint_targets: np.ndarray   # (n, 23) the policy's last joint targets [rad]


def first_hits(env, policy: str, hit: Callable[[dict], jax.Array], condition: str, num_starts: int, seed: int,
               max_s: float) -> HandoverStates:
    """The state at the first control step at which `hit(state.info)` holds, of each of `num_starts` rollouts of
    `policy` (artifact or checkpoint, deterministic: tanh of its mean) in `env` (a getup env on the CPU backend,
    its resets keyed from `seed`); rollouts that do not hit within `max_s` [s] are left out, identical states (a
    start drawn twice) kept once. Raises, naming `condition` (what `hit` tests), if none hits."""
    expert = load_expert(policy)
    if tuple(map(tuple, env.obs_terms)) != expert.obs_terms:
        raise ValueError(f"{policy}: observation terms {expert.obs_terms} are not the env's {env.obs_terms}")
    default_pose = jnp.asarray(env.manifest_fields()["default_pose"], jnp.float32)

    def act(state):
        action = jnp.tanh(expert.loc(state.obs[STUDENT_OBS_KEY]))
        return action, obsdef.action_to_targets(default_pose, jnp.asarray(expert.action_scale), action)

    reset, step, act = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step)), jax.jit(jax.vmap(act))
    state = reset(jax.random.split(jax.random.PRNGKey(seed), num_starts))
    found = np.zeros(num_starts, bool)
    qpos = np.zeros((num_starts, env.mj_model.nq))
    qvel = np.zeros((num_starts, env.mj_model.nv))
    targets = np.zeros((num_starts, expert.action_scale.shape[0]))
    for _ in range(int(round(max_s / env.dt))):
        action, target = act(state)
        state = step(state, action)
        new = ~found & np.asarray(hit(state.info))
        qpos[new], qvel[new], targets[new] = (np.asarray(state.data.qpos)[new], np.asarray(state.data.qvel)[new],
                                              np.asarray(target)[new])
        found |= new
        if found.all():
            break
    if not found.any():
        raise ValueError(f"{policy}: none of {num_starts} rollouts reached {condition} within {max_s} s: not a "
                         "trained expert for this hand-over")
    _, keep = np.unique(qpos[found].round(9), axis=0, return_index=True)
    keep = np.sort(keep)
    return HandoverStates(qpos[found][keep].astype(np.float32), qvel[found][keep].astype(np.float32),
                          targets[found][keep].astype(np.float32))
