"""common.events on scripted trajectories: known height sequences give known falls and attempts."""
import math

import numpy as np
import pytest

from common.events import (
    EventThresholds,
    GetupEvents,
    gate_while_standing,
    getup_events,
    kneel_gate_mask,
    reached_kneel,
    standing_mask,
    through_kneel_gate,
    up_z_from_quat,
)

DT_S = 0.02                 # 50 Hz series: the events must not depend on the tick rate
STAND_M, KNEEL_M, LIE_M = 0.66, 0.45, 0.15


def script(*segments):
    """segments: (height_from_m, height_to_m, duration_s[, up_z]) ramps, concatenated -> t, h, up_z."""
    heights, ups = [], []
    for seg in segments:
        h0, h1, dur = seg[:3]
        up = seg[3] if len(seg) > 3 else 1.0
        n = max(1, int(round(dur / DT_S)))
        heights.append(np.linspace(h0, h1, n, endpoint=False))
        ups.append(np.full(n, up))
    h = np.concatenate(heights)
    return np.arange(len(h)) * DT_S, h, np.concatenate(ups)


def events(*segments, th=EventThresholds()) -> GetupEvents:
    return getup_events(*script(*segments), th=th)


def test_standing_all_along_is_success_without_falls():
    ev = events((STAND_M, STAND_M, 3.0))
    assert ev == GetupEvents(success=True, time_to_stand_s=ev.time_to_stand_s, attempts=0, falls=0,
                             fall_times_s=[])
    assert math.isnan(ev.time_to_stand_s)


def test_fallen_start_one_clean_getup():
    # lie 1 s, rise through kneeling to standing in 2 s, stand 2 s
    ev = events((LIE_M, LIE_M, 1.0), (LIE_M, KNEEL_M, 1.0), (KNEEL_M, STAND_M, 1.0), (STAND_M, STAND_M, 2.0))
    assert ev.success and ev.attempts == 1 and ev.falls == 0 and ev.fall_times_s == [] and ev.started_down
    # stands at the first sample >= 0.6 m: 2 s + (0.6 - 0.45) / 0.21 m/s into the last ramp
    expected = 2.0 + (0.6 - KNEEL_M) / (STAND_M - KNEEL_M) * 1.0
    assert ev.time_to_stand_s == pytest.approx(expected, abs=DT_S)


def test_three_attempts_two_failed():
    # two rises to kneeling that collapse back to the ground, then a stand-up
    ev = events((LIE_M, LIE_M, 0.5),
                (LIE_M, KNEEL_M, 0.5), (KNEEL_M, LIE_M, 0.5),
                (LIE_M, KNEEL_M, 0.5), (KNEEL_M, 0.2, 0.5),
                (0.2, STAND_M, 1.0), (STAND_M, STAND_M, 1.5))
    assert ev.success and ev.attempts == 3 and ev.falls == 0


def test_failed_attempts_after_the_switch_height_are_counted_with_a_waist_series():
    """Two failed rises: the first stays below the switch, the second passes it (waist 0.1 m below the
    trunk here), then a stand-up. Without a waist series the count is None."""
    t, h, up = script((LIE_M, LIE_M, 0.5),
                      (LIE_M, KNEEL_M, 0.5), (KNEEL_M, LIE_M, 0.5),
                      (LIE_M, STAND_M, 0.7), (STAND_M, LIE_M, 0.5),
                      (LIE_M, STAND_M, 1.0), (STAND_M, STAND_M, 1.5))
    ev = getup_events(t, h, up, waist_height=h - 0.1, switch_height_m=0.5)
    assert ev.success and ev.attempts == 3 and ev.failed_after_switch == 1
    log = ev.attempt_log
    assert [a.outcome for a in log] == ["failed", "failed", "stood"]
    assert [a.switched for a in log] == [False, True, False]
    assert log[0].peak_trunk_m == pytest.approx(KNEEL_M, abs=0.02) and log[1].peak_trunk_m > 0.6
    assert all(a.start_s < a.end_s for a in log) and log[0].end_s <= log[1].start_s
    assert getup_events(t, h, up).failed_after_switch is None
    assert getup_events(t, h, up, waist_height=h - 0.1, switch_height_m=0.6).failed_after_switch == 0


def test_wobble_below_attempt_rise_is_not_an_attempt():
    wobble = [(LIE_M, LIE_M + 0.1, 0.2), (LIE_M + 0.1, LIE_M, 0.2)] * 5
    ev = events((LIE_M, LIE_M, 0.5), *wobble)
    assert not ev.success and ev.attempts == 0 and ev.falls == 0 and ev.attempt_log == []
    assert math.isnan(ev.time_to_stand_s)


def test_an_attempt_still_rising_at_the_end_is_logged_open():
    ev = events((LIE_M, LIE_M, 0.5), (LIE_M, KNEEL_M, 0.5))
    assert not ev.success and ev.attempts == 1
    (attempt,) = ev.attempt_log
    assert attempt.outcome == "open" and math.isnan(attempt.end_s) and not attempt.switched


def test_fall_during_walking_then_getup_counts_fall_time():
    ev = events((STAND_M, STAND_M, 2.0), (STAND_M, LIE_M, 0.5), (LIE_M, LIE_M, 1.0),
                (LIE_M, STAND_M, 1.5), (STAND_M, STAND_M, 1.5))
    assert ev.success and ev.falls == 1 and ev.attempts == 1
    # falls when the trunk crosses 0.35 m on the way down
    t_fall = 2.0 + (STAND_M - 0.35) / (STAND_M - LIE_M) * 0.5
    assert ev.fall_times_s[0] == pytest.approx(t_fall, abs=DT_S)
    t_stand = 3.5 + (0.6 - LIE_M) / (STAND_M - LIE_M) * 1.5
    assert ev.time_to_stand_s == pytest.approx(t_stand - ev.fall_times_s[0], abs=2 * DT_S)


def test_two_falls_two_getups_time_to_stand_is_first():
    one = [(STAND_M, LIE_M, 0.3), (LIE_M, LIE_M, 0.5), (LIE_M, STAND_M, 1.0), (STAND_M, STAND_M, 1.5)]
    ev = events((STAND_M, STAND_M, 1.0), *one, *one)
    assert ev.success and ev.falls == 2 and ev.attempts == 2
    assert ev.fall_times_s[1] > ev.fall_times_s[0] + 3.0
    assert ev.time_to_stand_s < 2.0


def test_ends_down_is_failure():
    ev = events((STAND_M, STAND_M, 1.0), (STAND_M, LIE_M, 0.3), (LIE_M, LIE_M, 2.0))
    assert not ev.success and ev.falls == 1 and ev.attempts == 0


def test_stand_not_held_long_enough_is_not_success():
    ev = events((LIE_M, LIE_M, 0.5), (LIE_M, STAND_M, 1.0), (STAND_M, STAND_M, 0.5))
    assert not ev.success and ev.attempts == 1 and math.isnan(ev.time_to_stand_s)


def test_stumble_and_kneel_above_fallen_height_is_not_a_fall():
    ev = events((STAND_M, STAND_M, 1.0), (STAND_M, 0.4, 0.5), (0.4, 0.4, 1.0), (0.4, STAND_M, 0.5),
                (STAND_M, STAND_M, 1.5))
    assert ev.success and ev.falls == 0 and ev.attempts == 0


def test_tall_but_tilted_is_not_standing():
    # trunk high but lying over a wall at 60 deg tilt: not a stand-up
    ev = events((LIE_M, LIE_M, 0.5), (LIE_M, STAND_M, 1.0, 0.5), (STAND_M, STAND_M, 2.0, 0.5))
    assert not ev.success and ev.attempts == 1
    mask = standing_mask([0.7, 0.7, 0.5], [1.0, 0.5, 1.0])
    assert mask.tolist() == [True, False, False]


def test_coarse_series_stand_up_between_samples_counts_one_attempt():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    ev = getup_events(t, [LIE_M, STAND_M, STAND_M, STAND_M], [1.0, 1.0, 1.0, 1.0])
    assert ev.success and ev.attempts == 1 and ev.time_to_stand_s == pytest.approx(1.0)


def test_thresholds_are_parameters():
    segs = ((LIE_M, LIE_M, 0.5), (LIE_M, LIE_M + 0.1, 0.3), (LIE_M + 0.1, LIE_M, 0.3))
    assert events(*segs).attempts == 0
    assert events(*segs, th=EventThresholds(attempt_rise_m=0.05)).attempts == 1


def test_up_z_from_quat():
    assert up_z_from_quat([1, 0, 0, 0]) == pytest.approx(1.0)
    half = math.sqrt(0.5)
    assert up_z_from_quat([half, half, 0, 0]) == pytest.approx(0.0, abs=1e-12)   # 90 deg roll
    assert up_z_from_quat([0, 0, 1, 0]) == pytest.approx(-1.0)                    # upside down
    assert up_z_from_quat(np.tile([2.0, 0, 0, 0], (3, 1))).shape == (3,)


@pytest.mark.parametrize("bad, match", [
    (dict(t=[0.0, 0.0]), "strictly increasing"),
    (dict(trunk_height=[0.6]), "samples"),
    (dict(up_z=[1.0, float("nan")]), "non-finite"),
    (dict(t=[]), "empty|samples"),
])
def test_bad_input_names_the_problem(bad, match):
    args = dict(t=[0.0, 0.1], trunk_height=[0.6, 0.6], up_z=[1.0, 1.0])
    args.update(bad)
    with pytest.raises(ValueError, match=match):
        getup_events(**args)


def test_bad_thresholds_rejected():
    with pytest.raises(ValueError, match="standing_trunk_threshold_m"):
        EventThresholds(standing_trunk_threshold_m=0.3)
    with pytest.raises(ValueError, match="attempt_rise_m"):
        EventThresholds(attempt_rise_m=0.0)


UP_Z_TILT_0_5_DEG, UP_Z_TILT_0_6_DEG = math.cos(math.radians(0.5)), math.cos(math.radians(0.6))


def test_kneel_gate_by_hand():
    # 0.4 − min(h, 0.4) < 0.005 m and √(2 − 2·u_z) < 0.01 (a tilt below 0.573°)
    h = np.array([0.3951, 0.3949, 0.67, 0.67, 0.67])
    up = np.array([1.0, 1.0, 1.0, UP_Z_TILT_0_5_DEG, UP_Z_TILT_0_6_DEG])
    assert kneel_gate_mask(h, up).tolist() == [True, False, True, True, False]


def test_the_gate_while_standing_is_its_share_of_the_standing_samples():
    h = np.array([0.2, 0.67, 0.67, 0.67, 0.67])
    up = np.array([1.0, 1.0, UP_Z_TILT_0_5_DEG, UP_Z_TILT_0_6_DEG, UP_Z_TILT_0_6_DEG])
    assert gate_while_standing(h, up) == pytest.approx(0.5)           # 2 of the 4 standing samples; lying not counted
    assert math.isnan(gate_while_standing(h[:1], up[:1]))


def test_through_kneel_gate_before_the_stand_up():
    upright_kneel = script((LIE_M, LIE_M, 0.5), (LIE_M, KNEEL_M, 0.5), (KNEEL_M, KNEEL_M, 0.5),
                           (KNEEL_M, STAND_M, 0.5), (STAND_M, STAND_M, 2.0))
    assert through_kneel_gate(*upright_kneel, getup_events(*upright_kneel)) is True
    # the same rise with the trunk tilted 10° until it stands: never through the gate
    t, h, up = upright_kneel
    tilted_up = np.where(h < 0.6, math.cos(math.radians(10.0)), 1.0)
    assert through_kneel_gate(t, h, tilted_up, getup_events(t, h, tilted_up)) is False
    stays_down = script((LIE_M, LIE_M, 2.0))
    assert through_kneel_gate(*stays_down, getup_events(*stays_down)) is None


def test_reached_kneel_is_stage_ones_aim_whatever_follows():
    kneels = script((LIE_M, LIE_M, 0.5), (LIE_M, KNEEL_M, 0.5), (KNEEL_M, KNEEL_M, 1.0))   # rises and holds it
    assert reached_kneel(kneels[1], kneels[2]) is True
    t, h, up = kneels
    assert reached_kneel(h, np.full_like(h, math.cos(math.radians(10.0)))) is False   # tilted: not the gate
    standing = script((STAND_M, STAND_M, 2.0))   # an upright stand meets the gate's numbers but is no kneel
    assert reached_kneel(standing[1], standing[2]) is False


def test_the_kneeling_posture_is_both_knees_down_and_no_leg_forward():
    from common.events import HIP_PITCHES, KNEE_PITCHES, kneeling_posture
    from messages.contract import joint_index
    q = np.zeros((3, 23))
    knees, hips = [joint_index(n) for n in KNEE_PITCHES], [joint_index(n) for n in HIP_PITCHES]
    q[:, knees], q[:, hips] = 1.9, -0.2                 # the kneel keyframe's
    q[1, knees[0]] = 1.0                                # one knee up: a half kneel or a crouch
    q[2, hips[1]] = -1.5                                # one leg forward: a half kneel
    assert kneeling_posture(q).tolist() == [True, False, False]


def test_the_kneel_hold_is_the_longest_unbroken_run_of_the_gate_in_the_posture():
    from common.events import kneel_hold_s
    h = np.array([0.2, 0.41, 0.41, 0.41, 0.2, 0.41, 0.41, 0.41, 0.41, 0.41])
    up = np.ones_like(h)
    kneeling = np.ones_like(h, bool)
    assert math.isclose(kneel_hold_s(h, up, kneeling, 0.02), 5 * 0.02)
    kneeling[6] = False                                  # a crouch breaks the second run
    assert math.isclose(kneel_hold_s(h, up, kneeling, 0.02), 3 * 0.02)
    assert kneel_hold_s(h, up * 0.99, kneeling, 0.02) == 0.0          # tilted 8°: never the gate
