"""The frame strip of one getup (training/evaluation/strip.py, `python -m training strip`): which moments it draws,
and a strip drawn from a held-back on-back start."""
from __future__ import annotations

import numpy as np
import PIL.Image
import pytest

from common import events
from common import model as t1model
from messages import contract
from training import cli, envs
from training.evaluation import strip

BASELINE = "policies/getup_baseline/getup_baseline.safetensors"
DT = 0.02


def _readings(trunk, up_z, kneeling):
    waist = np.asarray(trunk) - 0.1
    return np.stack([trunk, up_z, waist, kneeling], axis=1).astype(np.float32)


def test_the_strip_draws_the_kneel_and_the_stand_up():
    """Lying 1 s, kneeling upright at the gate's height 1 s, then standing: the kneel's first tick and the first
    stand-up are among the frames, in time order, the last one after the stand-up."""
    lying, kneel, stand = 50, 50, 200
    trunk = np.r_[np.full(lying, 0.2), np.full(kneel, contract.KNEEL_GATE_HEIGHT_M), np.full(stand + 1, 0.66)]
    up_z = np.r_[np.full(lying, 0.0), np.ones(kneel + stand + 1)]
    kneeling = np.r_[np.zeros(lying), np.ones(kneel), np.zeros(stand + 1)]
    t = np.arange(trunk.size) * DT
    ticks, labels = strip.moments(t, _readings(trunk, up_z, kneeling), frames=8)
    assert len(ticks) == len(labels) == 8 and ticks == sorted(ticks) and ticks[0] == 0
    assert ticks[labels.index(next(x for x in labels if x.endswith("kneel")))] == lying
    stood = ticks[labels.index(next(x for x in labels if x.endswith("stood")))]
    assert trunk[stood] >= contract.STANDING_TRUNK_THRESHOLD_M and stood > lying
    assert ticks[-1] == stood + round(strip.AFTER_STAND_S / DT)


def test_a_getup_that_never_stands_is_drawn_evenly():
    t = np.arange(101) * DT
    ticks, labels = strip.moments(t, _readings(np.full(101, 0.2), np.zeros(101), np.zeros(101)), frames=5)
    assert ticks == [0, 25, 50, 75, 100] and not any("kneel" in x or "stood" in x for x in labels)


def test_strip_cli_refuses_too_few_frames(capsys, tmp_path):
    assert cli.main(["strip", "--policy", BASELINE, "--frames", "2", "--out", str(tmp_path / "s.png")]) == 2
    assert "--frames 2: at least 4" in capsys.readouterr().err


def test_strip_cli_refuses_an_unknown_side(capsys, tmp_path):
    with pytest.raises(SystemExit):
        cli.main(["strip", "--policy", BASELINE, "--lying", "upside", "--out", str(tmp_path / "s.png")])
    assert "invalid choice: 'upside'" in capsys.readouterr().err


@pytest.mark.slow
def test_a_strip_of_an_on_back_start(tmp_path):
    out, seed, labels = strip.getup_strip(BASELINE, tmp_path / "strip.png", seconds=0.4, frames=4)
    image = np.asarray(PIL.Image.open(out))
    assert image.shape[:2] == (strip.FRAME_PX, 4 * strip.FRAME_PX) and image.std() > 0.0   # drawn, not blank
    assert len(labels) == 4 and seed >= 9500
    env = envs.make("getup", config_overrides={"backend": "cpu"})
    qpos, _ = env.fallen_starts(1, seed)
    assert events.lying_side(float(t1model.trunk_forward_z(np.asarray(qpos))[0])) == "on_back"
