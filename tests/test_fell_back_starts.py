"""The kneel task's fell-back starts (training/envs/starts/fell_back.py): where the keyframe chain's rise has just
failed an attempt. The failed-attempt rule is common/events' own; the slow test rolls the campaign's rise (CPU
physics) from a few starts."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common import events
from common import model as t1model
from training import envs
from training.envs.starts import fell_back

RISE = sorted(Path("training/campaigns/getup_keyframe/rise_rolled/checkpoints").glob("*"))[-1]
ROLL = sorted(Path("training/campaigns/getup_keyframe/roll_side/checkpoints").glob("*"))[-1]
SEED = 7_000_000
DT_S = 0.02


def _first_failed_tick(heights: np.ndarray) -> int:
    """The tick at which common/events.getup_events logs the first failed attempt of a lying robot's series."""
    t = np.arange(len(heights)) * DT_S
    ev = events.getup_events(t, heights, np.zeros_like(heights))
    failed = [a for a in ev.attempt_log if a.outcome == "failed"]
    return int(round(failed[0].end_s / DT_S)) if failed else -1


@pytest.mark.parametrize("heights", [
    [0.12, 0.10, 0.18, 0.28, 0.36, 0.30, 0.22, 0.15, 0.12],        # up to 0.36 m and back down
    [0.12, 0.12, 0.20, 0.24, 0.30, 0.29, 0.31, 0.40, 0.30, 0.24],  # a wobble on the way up, then the fall
    [0.12, 0.18, 0.22, 0.26, 0.30, 0.34, 0.38, 0.40, 0.40, 0.40],  # a rise that holds: no failed attempt
])
def test_the_failed_attempt_is_the_one_events_counts(heights):
    heights = np.asarray(heights)
    hit = fell_back.FailedAttempt()
    ticks = [k for k, h in enumerate(heights) if hit({"trunk_height": np.array([h, 0.12])})[0]]
    assert (ticks[0] if ticks else -1) == _first_failed_tick(heights)


def test_the_kneel_env_names_what_the_bank_needs():
    with pytest.raises(ValueError, match="fell_back.prob > 0 needs fell_back.rise_policy"):
        envs.make("getup_kneel", config_overrides={"backend": "cpu", "fell_back.prob": 0.2})
    with pytest.raises(ValueError, match="bank_starts must be ≥ 1"):
        fell_back.fell_back_bank(envs.make, str(RISE), "", 0, SEED, 2.0)


@pytest.mark.slow
def test_fell_back_starts_are_failed_rises_and_repeat_per_seed():
    qpos, qvel = fell_back.fell_back_bank(envs.make, str(RISE), str(ROLL), 4, SEED, 2.0)
    assert 1 <= len(qpos) <= 8 and qvel.shape == (len(qpos), t1model.load_model().nv)
    assert not qpos.flags.writeable and not qvel.flags.writeable
    assert np.all(qpos[:, 2] < events.KNEEL_GATE_HEIGHT_M)          # back down, short of the kneel
    fell_back.fell_back_bank.cache_clear()
    np.testing.assert_array_equal(fell_back.fell_back_bank(envs.make, str(RISE), str(ROLL), 4, SEED, 2.0)[0], qpos)
