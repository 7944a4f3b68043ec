"""Stage 1's collapse starts (training/envs/kneel_collapse.py): states along the robot's fall from the kneel
keyframe under weakened PD, up to a progress; the getup env starts its fallen share there (C physics)."""
from __future__ import annotations

import numpy as np
import pytest

from common import model as t1model
from training import envs
from training.envs import kneel_collapse

STARTS, SEED = 8, 700_000
SETTINGS = dict(gain_scale=0.1, push_rad_s=2.0, duration_s=2.0, ctrl_dt=0.02, supervisor=(25.0, 0.95))


def _bank(max_progress):
    return kneel_collapse.collapse_bank(STARTS, SEED, max_progress, **SETTINGS)


def _trunk_heights(qpos):
    return t1model.trunk_heights(t1model.load_model(), qpos)


def test_the_collapse_runs_from_the_kneel_toward_the_floor():
    qpos, qvel = kneel_collapse.collapses(STARTS, SEED, *(SETTINGS[k] for k in (
        "gain_scale", "push_rad_s", "duration_s", "ctrl_dt", "supervisor")))
    ticks = int(round(SETTINGS["duration_s"] / SETTINGS["ctrl_dt"]))
    assert qpos.shape[:2] == (STARTS, ticks + 1) and qvel.shape[:2] == (STARTS, ticks + 1)
    kneel = t1model.keyframe_qpos(t1model.load_model(), "kneel")
    np.testing.assert_allclose(qpos[:, 0], np.broadcast_to(kneel, qpos[:, 0].shape), atol=1e-6)
    start, end = _trunk_heights(qpos[:, 0]), _trunk_heights(qpos[:, -1])
    assert np.median(end) < 0.3 and np.all(end < start)  # the starts sink under the weak gains, most to the floor
    pushes = np.linalg.norm(qvel[:, 0, 3:5], axis=1)
    assert np.all(pushes >= 0.5 * SETTINGS["push_rad_s"] - 1e-6) and np.all(pushes <= SETTINGS["push_rad_s"] + 1e-6)


def test_max_progress_keeps_the_early_part_of_each_collapse():
    early, whole = _bank(0.5), _bank(1.0)
    ticks = int(round(SETTINGS["duration_s"] / SETTINGS["ctrl_dt"]))
    assert len(whole[0]) == STARTS * (ticks + 1) and len(early[0]) == STARTS * (ticks // 2 + 1)
    assert not early[0].flags.writeable                   # read-only: the rollouts are cached and shared
    assert np.median(_trunk_heights(early[0])) > np.median(_trunk_heights(whole[0]))
    assert len(_bank(0.0)[0]) == STARTS                   # progress 0: the kneel itself


def test_the_stage1_env_draws_its_fallen_share_from_the_collapse():
    env = envs.make("getup", config_overrides={
        "stage": "stage1", "fallen_bank_size": 2, "collapse_starts.prob": 0.6, "collapse_starts.bank_starts": STARTS,
        "collapse_starts.seed": SEED, "collapse_starts.max_progress": 0.5})
    ((prob, (qpos, qvel)),) = env._fallen_banks
    bank = _bank(0.5)
    assert prob == 0.6 and np.array_equal(np.asarray(qpos), bank[0]) and np.array_equal(np.asarray(qvel), bank[1])


def test_a_push_about_an_axis_in_0_to_180_degrees_lays_it_face_down():
    """push_axis_deg: the tipping push's axis from world x; (0°, 180°) pitches the kneeling robot forward,
    so every collapse ends prone (the trunk's forward axis pointing at the floor)."""
    qpos, _ = kneel_collapse.collapses(STARTS, SEED, *(SETTINGS[k] for k in (
        "gain_scale", "push_rad_s", "duration_s", "ctrl_dt", "supervisor")), (20.0, 160.0))
    assert np.all(t1model.trunk_forward_z(qpos[:, -1]) < -0.5)
    with pytest.raises(ValueError, match="push_axis_deg"):
        kneel_collapse.collapse_bank(STARTS, SEED, 0.5, **{**SETTINGS, "push_axis_deg": (160.0, 20.0)})


def test_collapse_start_settings_are_checked():
    with pytest.raises(ValueError, match="max_progress"):
        _bank(1.5)
    with pytest.raises(ValueError, match="gain_scale"):
        kneel_collapse.collapse_bank(STARTS, SEED, 0.5, **{**SETTINGS, "gain_scale": 0.0})
    with pytest.raises(ValueError, match="duration_s"):
        kneel_collapse.collapse_bank(STARTS, SEED, 0.5, **{**SETTINGS, "duration_s": 0.0})
    with pytest.raises(ValueError, match="at most 1"):
        envs.make("getup", config_overrides={
            "stage": "stage1", "fallen_bank_size": 2, "collapse_starts.prob": 0.6,
            "knockdown_starts.prob": 0.6, "knockdown_starts.joystick_policy": "policies/joystick/joystick.safetensors"})
