"""Starts where the keyframe chain's rise has just failed: the rise policy (task getup_kneel) rolled from where the
chain's rise begins (face-down falls and the roll's hand-overs, rise_kneels.rise_env) to the first tick of its first
failed attempt, in common/events' terms: the trunk had risen ATTEMPT_RISE_M above its lowest and is back down
ATTEMPT_RISE_M from the attempt's highest. A share of the kneel task's fallen starts is instead one of these states
(config fell_back), so that the rise learns to try again from a failed rise at the start of an episode as well as
late in one: the rise had learnt to lie still face down after a miss in a few falls in a hundred (its next
attempt pays only seconds later, lying still at once). Ours, not the seed's."""
from __future__ import annotations

import functools

import numpy as np
from ml_collections import config_dict

from common import events
from training.envs.starts.policy_rollout import first_hits
from training.envs.starts.rise_kneels import rise_env

MAX_RISE_S = 10.0   # [s] a start whose rise has not failed by then (it met the gate and held) is left out


def fell_back_config() -> config_dict.ConfigDict:
    """This share of the fallen starts is a state where `rise_policy` (artifact or checkpoint of task getup_kneel)
    has just failed a rise, from `bank_starts` face-down fallen starts and, where `roll_policy` is set, as many of
    the roll's hand-overs (seeds from `seed`, apart from the evaluations' 0 … and the other banks'); 0 = off."""
    return config_dict.create(prob=0.0, rise_policy="", roll_policy="", bank_starts=512, seed=7_000_000)


def fell_back_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    if env.make_env is None:
        raise ValueError("fell_back.prob > 0 needs an env made by training.envs.make (it rolls getup_kneel)")
    return fell_back_bank(env.make_env, str(group.rise_policy), str(group.roll_policy), int(group.bank_starts),
                          int(group.seed), float(env.config.fallen.prepare_s))


class FailedAttempt:
    """Called once per control step with the batch's info: True where that step ends the rollout's first failed
    attempt (common/events.getup_events' rule on the trunk height)."""

    def __init__(self, rise_m: float = events.ATTEMPT_RISE_M):
        self.rise_m = rise_m
        self.low = self.high = self.rising = None

    def __call__(self, info) -> np.ndarray:
        h = np.asarray(info["trunk_height"], np.float64)
        if self.low is None:
            self.low, self.high, self.rising = h.copy(), h.copy(), np.zeros(h.shape, bool)
        self.low = np.where(self.rising, self.low, np.minimum(self.low, h))
        self.rising |= h >= self.low + self.rise_m
        self.high = np.where(self.rising, np.maximum(self.high, h), h)
        return self.rising & (h <= self.high - self.rise_m)


@functools.lru_cache(maxsize=2)
def fell_back_bank(make_env, rise_policy: str, roll_policy: str, num_starts: int, seed: int,
                   prepare_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) at the first failed attempt of the rise's rollouts from `num_starts` face-down fallen starts
    (and as many roll hand-overs with `roll_policy`; seeds seed …, after a PREPARE ramp of prepare_s [s]). Cached
    (read-only arrays)."""
    if num_starts < 1:
        raise ValueError(f"fell_back: bank_starts must be ≥ 1, got {num_starts}")
    env = rise_env(make_env, roll_policy, num_starts, seed, prepare_s)
    states = first_hits(env, rise_policy, FailedAttempt(), "a failed rise (back down from an attempt)", num_starts,
                        seed, MAX_RISE_S)
    bank = states.qpos, states.qvel
    for array in bank:
        array.flags.writeable = False
    return bank
