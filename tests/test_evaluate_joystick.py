"""The joystick evaluation's reductions (training/evaluation/joystick.py) on synthetic series: fall cut-off,
RMS over all ticks, and the settled window after a command change."""
from __future__ import annotations

import math

import numpy as np

from training.evaluation import joystick as ej

DT = 0.02            # control tick [s]
STANDING = 0.66      # trunk height while walking [m]


def _series(n_eps=1, ticks=200, cmd=(0.4, 0.0, 0.0), vel=(0.4, 0.0, 0.0)):
    return {"cmd": np.tile(np.asarray(cmd, float), (n_eps, ticks, 1)),
            "vel": np.tile(np.asarray(vel, float), (n_eps, ticks, 1)),
            "trunk": np.full((n_eps, ticks), STANDING), "up_z": np.ones((n_eps, ticks))}


def test_perfect_tracking_scores_zero():
    s = ej.summarize(ej.episode_rows(_series(2), DT))
    assert s["episodes"] == 2 and s["fall_rate"] == 0.0
    assert s["rms_lin_vel_mps"] == 0.0 and s["rms_yaw_rate_radps"] == 0.0


def test_constant_errors_give_their_rms():
    # 0.3 m/s short in x, 0.4 m/s off in y -> 0.5 m/s linear error; yaw 0.2 rad/s short
    s = ej.summarize(ej.episode_rows(_series(cmd=(0.4, 0.0, 0.5), vel=(0.1, 0.4, 0.3)), DT))
    assert math.isclose(s["rms_lin_vel_mps"], 0.5, rel_tol=1e-9)
    assert math.isclose(s["rms_yaw_rate_radps"], 0.2, rel_tol=1e-9)


def test_ticks_after_a_fall_do_not_count():
    s = _series(2)
    s["vel"][1, 100:, 0] = 5.0           # wild readings once episode 1 lies on the ground
    s["trunk"][1, 100:] = 0.2
    rows = ej.episode_rows(s, DT)
    assert [r["fell"] for r in rows] == [False, True]
    assert rows[1]["ticks"] == 100 and rows[1]["lin2_sum"] == 0.0
    assert ej.summarize(rows)["fall_rate"] == 0.5


def test_settled_window_skips_one_second_after_a_command_change():
    s = _series(ticks=200)
    s["cmd"][0, 100:, 0] = 0.8           # step at tick 100; the robot lags for one second
    s["vel"][0, 100:150, 0] = 0.4
    s["vel"][0, 150:, 0] = 0.8
    row = ej.episode_rows(s, DT)[0]
    settle = round(ej.SETTLE_S / DT)
    assert row["settled_ticks"] == 200 - 2 * settle            # the start counts as a change too
    assert row["lin2_settled_sum"] == 0.0 and row["lin2_sum"] > 0.0


def test_yaw_breakdown_bins_commands_and_measures_the_turn_gain():
    s = _series(n_eps=2, ticks=100, cmd=(0.0, 0.0, 0.9), vel=(0.0, 0.0, 0.45))   # turns at half the rate
    s["cmd"][1, :, 2], s["vel"][1, :, 2] = -0.1, -0.1                            # small command, tracked
    bins = ej.yaw_by_command(s, ej.episode_rows(s, DT))
    assert [b["ticks"] for b in bins] == [100, 0, 0, 100]
    assert math.isclose(bins[0]["rms_radps"], 0.0, abs_tol=1e-12) and math.isclose(bins[0]["gain"], 1.0)
    assert math.isclose(bins[3]["rms_radps"], 0.45, rel_tol=1e-9) and math.isclose(bins[3]["gain"], 0.5)
    assert math.isnan(bins[1]["rms_radps"])
    assert math.isclose(bins[0]["bias_radps"], 0.0, abs_tol=1e-12) and math.isclose(bins[3]["bias_radps"], -0.45)


def test_yaw_breakdown_shows_a_steady_veer_as_bias():
    s = _series(n_eps=2, ticks=100, cmd=(0.4, 0.0, 0.1), vel=(0.4, 0.0, 0.02))   # veers right by 0.08 rad/s
    s["cmd"][1, :, 2], s["vel"][1, :, 2] = -0.1, -0.18
    bins = ej.yaw_by_command(s, ej.episode_rows(s, DT))
    assert math.isclose(bins[0]["bias_radps"], -0.08, rel_tol=1e-9)
    assert math.isclose(bins[0]["rms_radps"], 0.08, rel_tol=1e-9)


def test_step_response_follows_the_error_after_a_change_until_the_next_one():
    s = _series(n_eps=2, ticks=300)
    s["cmd"][:, 100:, 0] = 1.0                         # a 0.6 m/s step at tick 100 (2 s)
    lag = np.exp(-np.arange(200) * DT / 0.5)           # first-order response, time constant 0.5 s
    s["vel"][:, 100:, 0] = 1.0 - 0.6 * lag
    s["cmd"][1, 200:, 1] = 0.3                         # episode 1 changes again 2 s later
    s["vel"][1, 200:, 1] = 0.3
    r = ej.step_response(s, ej.episode_rows(s, DT), DT)
    assert r["changes"] == 3 and math.isclose(r["mean_step_mps"], (0.6 + 0.6 + 0.3) / 3)
    errs = dict(zip(ej.STEP_RESPONSE_S, r["mean_err_mps"]))
    assert math.isclose(errs[0.0], (0.6 + 0.6 + 0.6 * math.exp(-4)) / 3, rel_tol=1e-9)   # 2nd change: lag left
    # at 1 s: both first changes, and episode 1's second one (its x lag 3 s after the first)
    assert math.isclose(errs[1.0], (2 * 0.6 * math.exp(-2) + 0.6 * math.exp(-6)) / 3, rel_tol=1e-9)
    # at 2 s only episode 0's change counts: episode 1 changed again, and its second change has no 2 s left
    assert math.isclose(errs[2.0], 0.6 * math.exp(-4), rel_tol=1e-9)
