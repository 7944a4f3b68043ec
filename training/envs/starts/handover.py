"""Hand-over starts of the joystick env: the states in which the stitched teacher (training/distill/teacher.py: getup
expert below the waist's 0.5 m switch, joystick expert above) hands a rising robot to the joystick expert: a
getup artifact rising from fallen starts, at the first tick with the waist at the switch, with its last joint
targets. The joystick env starts a share of episodes there (config handover), so the joystick expert learns to
catch the lunge it is handed; ours, not the seed's. Rolled once on the host (CPU physics) when the env is built."""
from __future__ import annotations

from typing import Callable

from ml_collections import config_dict

from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.starts.policy_rollout import HandoverStates, first_hits

MAX_RISE_S = 10.0   # [s] a fallen start that has not handed over by then is left out


def handover_bank(make_env: Callable, getup_policy: str, num_starts: int, seed: int) -> HandoverStates:
    """Hand-over states of `getup_policy` (artifact or checkpoint) from `num_starts` random draws of a bank of
    `num_starts` seeded fallen starts (seed, seed + 1, …); identical states (a start drawn twice) kept once."""
    env = make_env("getup", config_overrides={"backend": "cpu", "start_probs": [1.0, 0.0, 0.0],
                                               "fallen.bank_starts": int(num_starts), "fallen.seed": int(seed),
                                               "obs_noise_scale": 0.0})
    return first_hits(env, getup_policy, lambda info: info["waist_height"] >= WAIST_SWITCH_HEIGHT_M,
                      f"the waist at the {WAIST_SWITCH_HEIGHT_M} m switch", num_starts, seed, MAX_RISE_S)


def handover_config() -> config_dict.ConfigDict:
    """The joystick env's hand-over starts: this share of episodes starts where the stitched teacher hands the
    getup expert `getup_policy`'s rise over, from `bank_starts` fallen starts (seeds from `seed`, apart from the
    evaluations' 0 …); 0 = standing starts only, as Playground's."""
    return config_dict.create(prob=0.0, getup_policy="", bank_starts=256, seed=100_000)


