"""Rise starts for stage 1 (ours, a reverse curriculum; the seed's stage 1 starts fallen): states along the
rises a stage-1 getup policy makes with the elastic harness on (assists.py).

Why: with the harness a stage-1 policy lifts its trunk to kneeling height; with the harness taken away it lies
(training/LESSONS.md, periods 1–3). Starting a share of the unassisted episodes part-way up the rises the
harness carried (qpos, qvel as they were) asks the policy for the last part of the rise first; lowering
`min_progress` stage by stage moves the starts back toward the floor, as start_path.py does for stage 2 along a
hand-made path, here along the policy's own rises.

`rise_bank` rolls the policy from seeded fallen starts in the stage-1 getup env with the harness, CPU physics
(a one-off host computation whatever backend trains), and keeps, from each episode whose trunk arrives near
the kneel (ARRIVE_TRUNK_M, upright within ARRIVE_UP_Z), the states of the ticks from the start to the arrival
whose progress (tick / arrival tick: 0 fallen, 1 arrived) is at least min_progress. The harness adds a tendon
and two sites, no degree of freedom: the states are the harness-free model's as they are.
"""
from __future__ import annotations

import functools
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np
from ml_collections import config_dict

from training.envs.experts import STUDENT_OBS_KEY, load_expert

ARRIVE_TRUNK_M = 0.38    # a rise arrives near the kneel (trunk 0.405 m there) at this trunk height [m] ...
ARRIVE_UP_Z = 0.95       # ... with the trunk this upright (18° of tilt at most)
MAX_RISE_S = 10.0        # [s] an episode that has not arrived by then gives no starts


def rise_config() -> config_dict.ConfigDict:
    """Stage 1's rise starts: this share of the getup env's fallen starts is instead a state along the rises
    `getup_policy` makes with the harness (stiffness [N/m], slack [m]) from `bank_starts` fallen starts (seeds from
    `seed`), at progress min_progress … 1 toward the kneel."""
    return config_dict.create(prob=0.0, getup_policy="", harness_n_per_m=400.0, harness_slack_m=0.45,
                              bank_starts=128, seed=600_000, min_progress=0.5)


def rise_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    return rise_bank(env.make_env, group.getup_policy, float(group.harness_n_per_m), float(group.harness_slack_m),
                     int(group.bank_starts), int(group.seed), float(group.min_progress))


def rise_bank(make_env: Callable, getup_policy: str, harness_n_per_m: float, harness_slack_m: float,
              num_starts: int, seed: int, min_progress: float) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) along the harnessed rises of `getup_policy` (artifact, checkpoint or run directory) from
    `num_starts` seeded fallen starts, from progress `min_progress` to the arrival (module docstring);
    read-only arrays."""
    if not 0.0 <= min_progress <= 1.0:
        raise ValueError(f"rise_starts.min_progress must be in [0, 1], got {min_progress}")
    qpos, qvel, arrival = harnessed_rises(make_env, getup_policy, harness_n_per_m, harness_slack_m, num_starts, seed)
    keep = [(i, t) for i in np.flatnonzero(arrival >= 0)
            for t in range(int(np.ceil(min_progress * arrival[i])), int(arrival[i]) + 1)]
    starts, ticks = np.array(keep).T
    bank = qpos[starts, ticks], qvel[starts, ticks]
    for array in bank:
        array.flags.writeable = False
    return bank


@functools.lru_cache(maxsize=4)
def harnessed_rises(make_env: Callable, getup_policy: str, harness_n_per_m: float, harness_slack_m: float,
                    num_starts: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rollouts: qpos (starts, ticks, nq), qvel (starts, ticks, nv) [float32] and each start's arrival
    tick (−1: none). Cached (read-only arrays): banks at other progresses pay nothing."""
    if harness_n_per_m <= 0.0:
        raise ValueError(f"rise_starts.harness_n_per_m must be > 0 (the rises are the harness's), got {harness_n_per_m}")
    env = make_env("getup", config_overrides={
        "backend": "cpu", "stage": "stage1", "stage1_start_probs": [1.0, 0.0, 0.0], "obs_noise_scale": 0.0,
        "fallen_bank_size": int(num_starts), "fallen_seed": int(seed),
        "harness.stiffness_n_per_m": float(harness_n_per_m), "harness.slack_trunk_height_m": float(harness_slack_m)})
    getup = load_expert(getup_policy, "getup")
    if tuple(map(tuple, env.obs_terms)) != getup.obs_terms:
        raise ValueError(f"{getup_policy}: observation terms {getup.obs_terms} are not the getup env's")

    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    act = jax.jit(jax.vmap(lambda obs: jnp.tanh(getup.loc(obs))))
    state = reset(jax.random.split(jax.random.PRNGKey(seed), num_starts))
    qpos, qvel = [np.asarray(state.data.qpos)], [np.asarray(state.data.qvel)]
    arrival = np.full(num_starts, -1)
    for tick in range(1, int(round(MAX_RISE_S / env.dt)) + 1):
        state = step(state, act(state.obs[STUDENT_OBS_KEY]))
        qpos.append(np.asarray(state.data.qpos))
        qvel.append(np.asarray(state.data.qvel))
        near = (np.asarray(state.info["trunk_height"]) >= ARRIVE_TRUNK_M) & \
            (np.asarray(state.info["up_z"]) >= ARRIVE_UP_Z)
        arrival[(arrival < 0) & near] = tick
        if (arrival >= 0).all():
            break
    if not (arrival >= 0).any():
        raise ValueError(f"{getup_policy}: no rise to trunk {ARRIVE_TRUNK_M} m (up_z ≥ {ARRIVE_UP_Z}) in "
                         f"{num_starts} harnessed fallen starts at {harness_n_per_m} N/m: not a rising stage-1 policy")
    rises = np.stack(qpos, 1).astype(np.float32), np.stack(qvel, 1).astype(np.float32), arrival
    for array in rises:
        array.flags.writeable = False
    return rises
