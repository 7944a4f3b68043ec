"""Stage 1's prone starts (training/envs/prone_path.py): settled states on a hand-made path from the kneel over
hands and knees to lying face down; the getup env starts its fallen share there (C physics)."""
from __future__ import annotations

import numpy as np
import pytest

from common import model as t1model
from training import envs
from training.envs import prone_path

STARTS, SEED = 8, 800_000
SETTINGS = dict(hands_knees_pitch_rad=1.4, target_noise_rad=0.1, settle_s=1.0, supervisor=(25.0, 0.95))


def _at(progress, **changes):
    return prone_path.prone_bank(STARTS, SEED, progress, progress, **{**SETTINGS, **changes})


def test_the_path_runs_from_the_kneel_over_hands_and_knees_to_face_down():
    model = t1model.load_model()
    points = prone_path.path_points(model, SETTINGS["hands_knees_pitch_rad"])
    assert [p for p, _, _ in points] == [0.0, 1.0, prone_path.PATH_END]
    np.testing.assert_array_equal(prone_path.pose_at(points, 0.0)[0], t1model.keyframe_qpos(model, "kneel"))
    q, pitch = prone_path.pose_at(points, 1.0)
    hip, shoulder = q[model.joint("Left_Hip_Pitch").qposadr[0]], q[model.joint("Right_Shoulder_Pitch").qposadr[0]]
    assert pitch == 1.4 and shoulder == -1.4 and hip == pytest.approx(-0.1 - 1.4)   # thighs vertical, arms down
    assert prone_path.pose_at(points, 1.5)[1] == pytest.approx((1.4 + np.pi / 2) / 2)
    with pytest.raises(ValueError, match="progress"):
        prone_path.pose_at(points, 2.5)


def test_hands_and_knees_rest_up_and_face_down_lies_on_its_front():
    """The path's middle is a posture the robot holds (the trunk near the kneel's height, leaning forward);
    its end lies face down as a robot that fell on its front does after PREPARE."""
    model = t1model.load_model()
    qpos, qvel = _at(1.0)
    assert qpos.shape == (STARTS, model.nq) and qvel.shape == (STARTS, model.nv) and not qpos.flags.writeable
    heights = t1model.trunk_heights(model, qpos.astype(np.float64))
    assert np.all((heights > 0.3) & (heights < 0.5)) and np.all(np.abs(qvel).max(axis=1) < 1.0)   # at rest
    assert np.all(t1model.trunk_forward_z(qpos) < -0.5)                                         # leaning forward
    prone, _ = _at(prone_path.PATH_END)
    assert np.all(t1model.trunk_heights(model, prone.astype(np.float64)) < 0.25)
    assert np.all(t1model.trunk_forward_z(prone) < -0.5)


def test_prone_start_settings_are_checked():
    with pytest.raises(ValueError, match="min_progress"):
        prone_path.prone_bank(STARTS, SEED, 1.5, 1.0, **SETTINGS)
    with pytest.raises(ValueError, match="hands_knees_pitch_rad"):
        _at(1.0, hands_knees_pitch_rad=0.0)
    with pytest.raises(ValueError, match="settle_s"):
        _at(1.0, settle_s=0.0)
    with pytest.raises(ValueError, match="at most 1"):
        envs.make("getup", config_overrides={"stage": "stage1", "fallen_bank_size": 2, "prone_starts.prob": 0.6,
                                             "collapse_starts.prob": 0.6})


def test_the_stage1_env_draws_its_fallen_share_from_the_path():
    env = envs.make("getup", config_overrides={
        "stage": "stage1", "fallen_bank_size": 2, "prone_starts.prob": 0.5, "prone_starts.bank_starts": STARTS,
        "prone_starts.seed": SEED, "prone_starts.min_progress": 0.7})
    ((prob, (qpos, qvel)),) = env._fallen_banks
    bank = prone_path.prone_starts(env, env.config.prone_starts)
    assert prob == 0.5 and np.array_equal(np.asarray(qpos), bank[0]) and np.array_equal(np.asarray(qvel), bank[1])
