"""Starts where the keyframe chain's rise hands the robot over to the stand: the rise policy (task getup_kneel)
rolled from face-down fallen starts and from the roll's hand-overs (rolled.py), to the first tick at which the
trunk is at the kneel gate's height within each hand-over's upright bound (common/events.kneel_gate with
`up_errors`: the kneel band's 2.9° and §4.8's gate's 0.57° by default), with its velocities. A share of the stand
task's starts is instead one of these states (config rise_kneels), so the stand learns to rise from the kneels the
rise really reaches, not only from the kneel keyframe at rest. Ours, not the seed's."""
from __future__ import annotations

import functools

import numpy as np
from ml_collections import config_dict

from common import events
from training.envs.starts.policy_rollout import first_hits

MAX_RISE_S = 10.0   # [s] a fallen start the rise has not brought to the hand-over by then is left out
ROLLED_SHARE = 0.5  # of the rise's rollouts, the share that starts at the roll's hand-over (the rest face down)


def rise_kneels_config() -> config_dict.ConfigDict:
    """This share of the stand task's starts is a state where `rise_policy` (artifact or checkpoint of task
    getup_kneel) first meets the kneel gate's height within one of `up_errors` (‖u − e_z‖ bounds), risen from
    `bank_starts` face-down fallen starts and, where `roll_policy` is set, as many of the roll's hand-overs (seeds
    from `seed`, apart from the evaluations' 0 … and the other banks'); 0 = off."""
    return config_dict.create(prob=0.0, rise_policy="", roll_policy="", bank_starts=256, seed=6_000_000,
                              up_errors=[events.KNEEL_BAND_UP_ERROR, events.KNEEL_GATE_UP_ERROR])


def rise_kneels_bank(make_env, group, prepare_s: float) -> tuple[np.ndarray, np.ndarray]:
    if make_env is None:
        raise ValueError("rise_kneels.prob > 0 needs an env made by training.envs.make (it rolls getup_kneel)")
    up_errors = tuple(float(e) for e in group.up_errors)
    if not up_errors or not all(0.0 < e < 2.0 for e in up_errors):
        raise ValueError(f"rise_kneels.up_errors must be ‖u − e_z‖ bounds in (0, 2), got {list(group.up_errors)}")
    return kneel_bank(make_env, str(group.rise_policy), str(group.roll_policy), int(group.bank_starts),
                      int(group.seed), prepare_s, up_errors)


def rise_env(make_env, roll_policy: str, num_starts: int, seed: int, prepare_s: float):
    """The kneel task (CPU physics, no observation noise) whose starts are where the chain's rise begins: face-down
    fallen starts (seeds seed …) and, with `roll_policy`, as many of the roll's hand-overs (seeds after them)."""
    overrides = {"backend": "cpu", "start_probs": [1.0, 0.0, 0.0], "fallen.bank_starts": num_starts,
                 "fallen.seed": seed, "fallen.prepare_s": prepare_s, "fallen.side_weights": [1, 0, 0],
                 "obs_noise_scale": 0.0}
    if roll_policy:
        overrides.update({"rolled_starts.prob": ROLLED_SHARE, "rolled_starts.roll_policy": roll_policy,
                          "rolled_starts.bank_starts": num_starts, "rolled_starts.seed": seed + num_starts})
    return make_env("getup_kneel", config_overrides=overrides)


@functools.lru_cache(maxsize=2)
def kneel_bank(make_env, rise_policy: str, roll_policy: str, num_starts: int, seed: int, prepare_s: float,
               up_errors: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) of the rise's first hand-over state for each bound in `up_errors`, from `num_starts` rollouts
    (seeds seed … seed + num_starts − 1, after a PREPARE ramp of prepare_s [s]). Cached (read-only arrays)."""
    if num_starts < 1:
        raise ValueError(f"rise_kneels: bank_starts must be ≥ 1, got {num_starts}")
    env = rise_env(make_env, roll_policy, num_starts, seed, prepare_s)
    qpos, qvel = [], []
    for up_error in up_errors:
        def at_handover(info, bound=up_error):
            return events.kneel_gate(info["trunk_height"], info["up_z"], np, bound)
        states = first_hits(env, rise_policy, at_handover,
                            f"the kneel gate's height within ‖u − e_z‖ < {up_error}", num_starts, seed, MAX_RISE_S)
        qpos.append(states.qpos)
        qvel.append(states.qvel)
    bank = np.concatenate(qpos), np.concatenate(qvel)
    for array in bank:
        array.flags.writeable = False
    return bank
