"""Hand-over starts of the joystick env: the states in which the stitched teacher (training/distill/teacher.py: getup
expert below the waist's 0.5 m switch, joystick expert above) hands a rising robot to the joystick expert: a
getup artifact rising from fallen starts, at the first tick with the waist at the switch, with its last joint
targets. The joystick env starts a share of episodes there (config handover), so the joystick expert learns to
catch the lunge it is handed; ours, not the seed's. Rolled once on the host (CPU physics) when the env is built."""
from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from ml_collections import config_dict

from common import observation as obsdef
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.experts import STUDENT_OBS_KEY, load_expert

MAX_RISE_S = 10.0   # [s] a fallen start that has not handed over by then is left out


class HandoverBank(NamedTuple):
    qpos: np.ndarray            # (n, nq)
    qvel: np.ndarray            # (n, nv); the free joint's linear part in world axes [m/s]
    joint_targets: np.ndarray   # (n, 23) the getup expert's last joint targets [rad]


def handover_bank(make_env: Callable, getup_policy: str, num_starts: int, seed: int) -> HandoverBank:
    """Hand-over states of `getup_policy` (artifact or checkpoint) from `num_starts` random draws of a bank of
    `num_starts` seeded fallen starts (seed, seed + 1, …); identical states (a start drawn twice) kept once."""
    env = make_env("getup", config_overrides={"backend": "cpu", "start_probs": [1.0, 0.0, 0.0],
                                               "fallen.bank_starts": int(num_starts), "fallen.seed": int(seed),
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


def handover_config() -> config_dict.ConfigDict:
    """The joystick env's hand-over starts: this share of episodes starts where the stitched teacher hands the
    getup expert `getup_policy`'s rise over, from `bank_starts` fallen starts (seeds from `seed`, apart from the
    evaluations' 0 …); 0 = standing starts only, as Playground's."""
    return config_dict.create(prob=0.0, getup_policy="", bank_starts=256, seed=100_000)


