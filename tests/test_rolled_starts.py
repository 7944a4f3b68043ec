"""The kneel task's rolled starts (training/envs/starts/rolled.py): where the keyframe chain's roll hands over to
the face-down rise. The slow test rolls the campaign's roll policy (CPU physics) from a few fallen starts."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common import events
from common import model as t1model
from training import envs
from training.envs.starts import rolled
from training.envs.starts.policy_rollout import first_hits

ROLL = sorted(Path("training/campaigns/getup_keyframe/roll_side/checkpoints").glob("*"))[-1]
BANK_STARTS = 6
SEED = 5_000_000


@pytest.mark.parametrize("over, why", [({"rolled_starts.prob": 0.3}, "needs rolled_starts.roll_policy"),
                                       ({"rolled_starts.prob": 0.3, "rolled_starts.roll_policy": str(ROLL),
                                         "demo_starts.prob": 0.8, "demo_starts.folder": "x"}, "at most 1")])
def test_kneel_env_refuses_a_bad_rolled_config(over, why):
    with pytest.raises(ValueError, match=why):
        envs.make("getup_kneel", config_overrides={"backend": "cpu", **over})


def test_a_bank_needs_starts():
    with pytest.raises(ValueError, match="bank_starts must be ≥ 1"):
        rolled.rolled_bank(envs.make, str(ROLL), 0, SEED, 2.0)


@pytest.mark.slow
def test_rolled_starts_lie_face_down_and_still_and_repeat_per_seed():
    qpos, qvel = rolled.rolled_bank(envs.make, str(ROLL), BANK_STARTS, SEED, 2.0)
    assert 1 <= len(qpos) <= BANK_STARTS and qvel.shape == (len(qpos), t1model.load_model().nv)
    assert not qpos.flags.writeable and not qvel.flags.writeable
    forward_z = t1model.trunk_forward_z(qpos)
    assert np.all(forward_z < -events.ROLLED_FORWARD_Z)                  # face down: the rise's hand-over
    assert np.all(np.linalg.norm(qvel[:, 3:6], axis=1) < events.ROLLED_MAX_ANG_SPEED_RAD_S)
    rolled.rolled_bank.cache_clear()
    again = rolled.rolled_bank(envs.make, str(ROLL), BANK_STARTS, SEED, 2.0)
    np.testing.assert_array_equal(again[0], qpos)


@pytest.mark.slow
def test_a_policy_that_never_hands_over_is_named_with_the_condition():
    env = envs.make("getup_roll", config_overrides={"backend": "cpu", "fallen.bank_starts": 2})
    with pytest.raises(ValueError, match="none of 2 rollouts reached the trunk in orbit within 0.1 s"):
        first_hits(env, str(ROLL), lambda info: info["trunk_height"] > 100.0, "the trunk in orbit", 2, 0, 0.1)
