"""Starts where the keyframe chain hands the roll over to the face-down rise: the roll policy (task getup_roll)
rolled from on-back and side fallen starts to the first tick of common/events.rolled_face_down. A share of the
kneel task's fallen starts is instead one of these states (config rolled_starts), so the rise learns from the
states the chain gives it, not only from robots that fell face down. Ours, not the seed's."""
from __future__ import annotations

import functools

import numpy as np
from ml_collections import config_dict

from training.envs.starts.policy_rollout import first_hits

MAX_ROLL_S = 5.0    # [s] a start the roll has not turned face down by then is left out (the roll task's episode)


def rolled_config() -> config_dict.ConfigDict:
    """This share of the fallen starts is a state where `roll_policy` (artifact or checkpoint of task getup_roll)
    hands over to the rise, rolled from `bank_starts` on-back and side fallen starts (seeds from `seed`, apart from
    the evaluations' 0 … and the other banks'); 0 = off."""
    return config_dict.create(prob=0.0, roll_policy="", bank_starts=512, seed=5_000_000)


def rolled_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    if env.make_env is None:
        raise ValueError("rolled_starts.prob > 0 needs an env made by training.envs.make (it rolls getup_roll)")
    return rolled_bank(env.make_env, str(group.roll_policy), int(group.bank_starts), int(group.seed),
                       float(env.config.fallen.prepare_s))


@functools.lru_cache(maxsize=2)
def rolled_bank(make_env, roll_policy: str, num_starts: int, seed: int,
                prepare_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) at the roll's hand-over from `num_starts` draws of the on-back and side starts among fallen
    seeds seed … seed + num_starts − 1 (after a PREPARE ramp of prepare_s [s]). Cached (read-only arrays)."""
    if num_starts < 1:
        raise ValueError(f"rolled_starts: bank_starts must be ≥ 1, got {num_starts}")
    env = make_env("getup_roll", config_overrides={
        "backend": "cpu", "start_probs": [1.0, 0.0, 0.0], "fallen.bank_starts": num_starts, "fallen.seed": seed,
        "fallen.prepare_s": prepare_s, "fallen.side_weights": [0, 1, 1], "obs_noise_scale": 0.0})
    states = first_hits(env, roll_policy, lambda info: info["rolled"], "face down and still (the rise's hand-over)",
                        num_starts, seed, MAX_ROLL_S)
    bank = states.qpos, states.qvel
    for array in bank:
        array.flags.writeable = False
    return bank
