"""Stage 1's rise starts (training/envs/rise_bank.py): states along the rises the campaign's harnessed stage-1
policy makes, from a progress on; the getup env starts its fallen share there. Rolls the committed campaign
checkpoint (CPU physics)."""
from __future__ import annotations

import numpy as np
import pytest

from common import model as t1model
from training import envs
from training.envs import rise_bank

HARNESSED = "training/campaigns/getup_keyframe/rise_harnessed"
STARTS, SEED = 8, 600_000


def _bank(min_progress):
    return rise_bank.rise_bank(envs.make, HARNESSED, 400.0, 0.45, STARTS, SEED, min_progress)


def _trunk_heights(qpos):
    return t1model.trunk_heights(t1model.load_model(), qpos)


@pytest.mark.slow
def test_the_bank_holds_the_harnessed_rises_from_the_floor_to_near_the_kneel():
    whole, late = _bank(0.0), _bank(0.5)
    assert len(late) == 2 and late[0].shape[1] == 30 and late[1].shape[1] == 29
    assert 0 < len(late[0]) < len(whole[0])                  # the later half of each rise only
    assert not late[0].flags.writeable                       # read-only: the rollouts are cached and shared
    h_whole, h_late = _trunk_heights(whole[0]), _trunk_heights(late[0])
    assert h_whole.min() < 0.25                              # a rise begins on the floor
    assert h_late.max() >= rise_bank.ARRIVE_TRUNK_M          # and ends near the kneel
    assert np.median(h_late) > np.median(h_whole)


@pytest.mark.slow
def test_the_stage1_env_draws_its_fallen_share_from_the_bank():
    """The share goes to the getup env's start banks, which _start_state draws from as the landing banks."""
    env = envs.make("getup", config_overrides={
        "stage": "stage1", "fallen_bank_size": 2, "rise_starts.prob": 0.7, "rise_starts.getup_policy": HARNESSED,
        "rise_starts.bank_starts": STARTS, "rise_starts.seed": SEED, "rise_starts.min_progress": 0.5})
    ((prob, (qpos, qvel)),) = env._fallen_banks
    bank = _bank(0.5)
    assert prob == 0.7 and np.array_equal(np.asarray(qpos), bank[0]) and np.array_equal(np.asarray(qvel), bank[1])


def test_rise_start_settings_are_checked():
    with pytest.raises(ValueError, match="rise_starts.getup_policy"):
        envs.make("getup", config_overrides={"stage": "stage1", "fallen_bank_size": 2, "rise_starts.prob": 0.5})
    with pytest.raises(ValueError, match="min_progress"):
        rise_bank.rise_bank(envs.make, HARNESSED, 400.0, 0.45, STARTS, SEED, 1.5)
    with pytest.raises(ValueError, match="harness_n_per_m"):
        rise_bank.harnessed_rises(envs.make, HARNESSED, 0.0, 0.45, STARTS, SEED)
    with pytest.raises(ValueError, match="at most 1"):
        envs.make("getup", config_overrides={
            "stage": "stage1", "fallen_bank_size": 2, "rise_starts.prob": 0.6, "rise_starts.getup_policy": HARNESSED,
            "rise_starts.bank_starts": STARTS, "rise_starts.seed": SEED, "rise_starts.min_progress": 0.5,
            "knockdown_starts.prob": 0.6, "knockdown_starts.joystick_policy": "policies/joystick/joystick.safetensors"})
