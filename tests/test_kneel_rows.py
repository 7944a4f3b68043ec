"""The keyframe getup's per-episode figures (training/evaluation/kneel_rows.py): through the kneel band or §4.8's
gate in the kneeling posture, and the power while standing, on scripted series."""
import math

import numpy as np
import pytest

from common import events
from training.evaluation import batch, kneel_rows

DT_S = 0.02
LIE_M, KNEEL_M, STAND_M = 0.15, events.KNEEL_GATE_HEIGHT_M, 0.66


def ramp(h0, h1, seconds):
    return np.linspace(h0, h1, int(round(seconds / DT_S)), endpoint=False)


def episode(kneel_tilt_deg, kneeling=True, stand_s=3.0):
    """Lying 0.5 s, up to the kneel's height, 1 s there, up to standing, standing stand_s; the trunk tilted
    kneel_tilt_deg until it stands."""
    h = np.concatenate([ramp(LIE_M, LIE_M, 0.5), ramp(LIE_M, KNEEL_M, 0.5), ramp(KNEEL_M, KNEEL_M, 1.0),
                        ramp(KNEEL_M, STAND_M, 0.5), ramp(STAND_M, STAND_M, stand_s)])
    up = np.where(h < events.STANDING_TRUNK_THRESHOLD_M, math.cos(math.radians(kneel_tilt_deg)), 1.0)
    t = np.arange(h.size) * DT_S
    posture = ((h > 0.3) & (h < 0.5) & kneeling).astype(float)
    return t, np.stack([h, up, h - 0.1, posture], axis=1)


@pytest.mark.parametrize("tilt_deg, gate, band", [(0.3, 1.0, 1.0), (2.0, 0.0, 1.0), (5.0, 0.0, 0.0)])
def test_through_the_kneel_band_and_the_gate_by_the_kneel_s_tilt(tilt_deg, gate, band):
    t, readings = episode(tilt_deg)
    ev = events.getup_events(t, readings[:, 0], readings[:, 1])
    row = kneel_rows.kneel_row(t, readings, ev, np.zeros(t.size - 1))
    assert (row["through_kneel_gate"], row["through_kneel_band"]) == (gate, band)


def test_through_the_kneel_needs_the_kneeling_posture_where_the_series_has_it():
    t, readings = episode(0.3, kneeling=False)
    ev = events.getup_events(t, readings[:, 0], readings[:, 1])
    row = kneel_rows.kneel_row(t, readings, ev, np.zeros(t.size - 1))
    assert row["through_kneel_gate"] == 0.0 and row["through_kneel_band"] == 0.0 and row["kneeled"] == 0.0
    without_posture = kneel_rows.kneel_row(t, readings[:, :3], ev, np.zeros(t.size - 1))
    assert without_posture["through_kneel_gate"] == 1.0 and math.isnan(without_posture["kneeled"])


def test_power_while_standing_is_the_energy_after_the_stand_up_over_its_time():
    t, readings = episode(0.3, stand_s=4.0)
    ev = events.getup_events(t, readings[:, 0], readings[:, 1])
    energy = np.where(t[:-1] < t[0] + ev.time_to_stand_s - 1e-9, 50.0, 2.0)   # [J] per 0.02 s tick: 100 W standing
    assert kneel_rows.standing_power_W(t, ev, energy) == pytest.approx(100.0, rel=0.02)
    short_t, short = episode(0.3, stand_s=1.5)     # stood less than 2 s before the end: not counted
    short_ev = events.getup_events(short_t, short[:, 0], short[:, 1])
    assert math.isnan(kneel_rows.standing_power_W(short_t, short_ev, np.ones(short_t.size - 1)))
    lying = events.getup_events(t, np.full(t.size, LIE_M), np.ones(t.size))
    assert math.isnan(kneel_rows.standing_power_W(t, lying, np.ones(t.size - 1)))


def test_the_report_s_side_table_splits_by_how_the_start_lay():
    t, readings = episode(0.3)
    row = batch.episode_row(t, readings, {k: np.ones(t.size - 1) for k in (
        "energy_J", "max_energy_J", "max_torque_Nm", "torque_integral", "max_qacc", "qacc_integral",
        "contact_force_N", "contact_force_z_N")})
    rows = [{**row, "start_forward_z": -0.9}, {**row, "start_forward_z": 0.9, "success": False}]
    results = {"policy": {"run": {"rows": rows}}}
    table = "\n".join(kneel_rows.side_table(results, batch.summarize, batch._fmt))
    assert "policy: face down (1)" in table and "policy: on back (1)" in table and "side" not in table.split("\n")[2]
    assert "| standing at the end (share) | 1.000 | 0.000 |" in table
