"""Hand-over starts of the joystick env: the states in which the stitched teacher (training/distill/teacher.py: getup
expert below the waist's 0.5 m switch, joystick expert above) hands a rising robot to the joystick expert, at the
first tick with the waist at the switch, with the getup expert's last joint targets. The getup expert is either
one artifact rising from fallen starts, or the keyframe chain: its stand rising from the kneels where the chain's
rise hands over (starts/rise_kneels.py; the waist passes the switch only in the stand). The joystick env starts a
share of episodes there (config handover), so the joystick expert learns to catch the lunge it is handed; ours,
not the seed's. Rolled once on the host (CPU physics) when the env is built."""
from __future__ import annotations

from typing import Callable

from ml_collections import config_dict

from common import events
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.envs.starts.policy_rollout import HandoverStates, first_hits

MAX_RISE_S = 10.0   # [s] a start that has not handed over by then is left out
AT_SWITCH = f"the waist at the {WAIST_SWITCH_HEIGHT_M} m switch"


def _at_switch(info):
    return info["waist_height"] >= WAIST_SWITCH_HEIGHT_M


def handover_config() -> config_dict.ConfigDict:
    """The joystick env's hand-over starts: this share of episodes starts where the stitched teacher hands the
    getup expert `getup_policy`'s rise over, from `bank_starts` starts (seeds from `seed`, apart from the
    evaluations' 0 …); 0 = standing starts only, as Playground's. With `rise_policy` set the getup expert is the
    keyframe chain and `getup_policy` its stand, which rises from where `rise_policy` (on-back falls rolled over
    by `roll_policy` first) meets the kneel gate's height within ‖u − e_z‖ < `up_error`: the chain's hand-over
    (the kneel band's by default, the student's teacher's)."""
    return config_dict.create(prob=0.0, getup_policy="", bank_starts=256, seed=100_000, rise_policy="",
                              roll_policy="", up_error=events.KNEEL_BAND_UP_ERROR)


def handover_bank(make_env: Callable, group: config_dict.ConfigDict) -> HandoverStates:
    """Hand-over states of config group `group` (handover_config's fields) from `bank_starts` random draws of
    `bank_starts` seeded starts (seed, seed + 1, …); identical states (a start drawn twice) kept once."""
    num_starts, seed = int(group.bank_starts), int(group.seed)
    if group.rise_policy:
        return chain_handover_bank(make_env, str(group.getup_policy), str(group.rise_policy), str(group.roll_policy),
                                   float(group.up_error), num_starts, seed)
    env = make_env("getup", config_overrides={"backend": "cpu", "start_probs": [1.0, 0.0, 0.0],
                                               "fallen.bank_starts": num_starts, "fallen.seed": seed,
                                               "obs_noise_scale": 0.0})
    return first_hits(env, str(group.getup_policy), _at_switch, AT_SWITCH, num_starts, seed, MAX_RISE_S)


def chain_handover_bank(make_env: Callable, stand_policy: str, rise_policy: str, roll_policy: str, up_error: float,
                        num_starts: int, seed: int) -> HandoverStates:
    """The keyframe chain's hand-overs to the joystick expert: `stand_policy` rolled from the chain's rise → stand
    hand-overs at ‖u − e_z‖ < up_error (rise_kneels.kneel_bank, `num_starts` fallen seeds from `seed`) to the
    waist's switch."""
    if not 0.0 < up_error < 2.0:
        raise ValueError(f"handover.up_error must be a ‖u − e_z‖ bound in (0, 2), got {up_error}")
    env = make_env("getup_stand", config_overrides={
        "backend": "cpu", "obs_noise_scale": 0.0, "reverse_curriculum.max_progress": 0.0,
        "rise_kneels.prob": 1.0, "rise_kneels.rise_policy": rise_policy, "rise_kneels.roll_policy": roll_policy,
        "rise_kneels.bank_starts": num_starts, "rise_kneels.seed": seed, "rise_kneels.up_errors": [up_error]})
    return first_hits(env, stand_policy, _at_switch, AT_SWITCH, num_starts, seed, MAX_RISE_S)
