"""The keyframe getup's per-episode figures of the batch evaluation (batch.py), and its table by lying side.

Per episode (kneel_row): whether the robot rose through the kneel before its first stand-up, at §4.8's gate and
at the kneel band (common/events.through_kneel_gate, in the kneeling posture where the series has it); how long
it held the gate in that posture; the power while standing (the energy after the first stand-up over the time
after it [W], for episodes that stood at least STANDING_POWER_MIN_S before their end; the report gives the
median: a stand that chatters burns hundreds of watts, a quiet one tens).
"""
from __future__ import annotations

import math

import numpy as np

from common import events

STANDING_POWER_MIN_S = 2.0   # [s] after the first stand-up, for an episode's power while standing to count
SIDE_KEYS = (("standing at the end (share)", "success_rate", "{:.3f}"),
             ("attempts per fall", "attempts_per_fall", "{:.2f}"),
             ("median time to stand [s]", "median_time_to_stand_s", "{:.2f}"),
             ("through §4.8's gate in the kneeling posture (share of stand-ups)", "through_kneel_gate", "{:.2f}"),
             ("through the kneel band in the kneeling posture (share of stand-ups)", "through_kneel_band",
              "{:.2f}"),
             ("median power while standing [W]", "standing_power_W", "{:.0f}"))


def kneel_row(t, readings, ev: events.GetupEvents, energy_J) -> dict:
    """One episode's kneel and standing-power figures from its readings (T + 1, 3 or 4: trunk height, up_z,
    waist height[, kneeling posture]) at times t [s], its events and per-tick energy (T,) [J]. Without the
    posture the kneel's hold figures are nan and the through-the-kneel shares do not require the posture."""
    h, u = readings[:, 0], readings[:, 1]
    kneeling = readings[:, 3] > 0.5 if readings.shape[1] >= 4 else None
    gate = events.through_kneel_gate(t, h, u, ev, kneeling=kneeling)
    band = events.through_kneel_gate(t, h, u, ev, kneeling=kneeling, up_error_max=events.KNEEL_BAND_UP_ERROR)
    row = {"through_kneel_gate": math.nan if gate is None else float(gate),
           "through_kneel_band": math.nan if band is None else float(band),
           "standing_power_W": standing_power_W(t, ev, energy_J)}
    if kneeling is None:
        return {**row, "kneel_hold_s": math.nan, "kneeled": math.nan, "kneel_held": math.nan}
    hold = events.kneel_hold_s(h, u, kneeling, float(t[1] - t[0]))
    return {**row, "kneel_hold_s": hold, "kneeled": float(hold > 0),
            "kneel_held": float(hold >= events.KNEEL_HOLD_S - 1e-9) if hold > 0 else math.nan}


def standing_power_W(t, ev: events.GetupEvents, energy_J) -> float:
    """Energy after the first stand-up over the time after it [W]; nan if the robot never stood up, or stood less
    than STANDING_POWER_MIN_S before the series ends. Tick k's energy is spent between samples k and k + 1."""
    if math.isnan(ev.time_to_stand_s):
        return math.nan
    stand_s = t[0] + ev.time_to_stand_s + (0.0 if ev.started_down else ev.fall_times_s[0] - t[0])
    first = int(np.searchsorted(t, stand_s - 1e-9))
    after_s = float(t[-1] - t[first])
    if after_s < STANDING_POWER_MIN_S:
        return math.nan
    return float(np.sum(energy_J[first:]) / after_s)


def side_summary(rows: list[dict], summarize) -> dict[str, dict]:
    """`summarize` (batch.summarize) over the episodes that started lying each way, by events.LYING_SIDES."""
    out = {}
    for side in events.LYING_SIDES:
        these = [r for r in rows if events.lying_side(r.get("start_forward_z", 0.0)) == side]
        if these:
            out[side] = summarize(these)
    return out


def side_table(results: dict, summarize, fmt) -> list[str]:
    """Markdown: SIDE_KEYS for each policy and each lying side (the starts' share in the header)."""
    first = next(iter(results.values()))["run"]["rows"]
    sides = side_summary(first, summarize)
    header = ["metric"] + [f"{name}: {side.replace('_', ' ')} ({s['episodes']})" for name in results
                           for side, s in sides.items()]
    lines = ["By lying side at the start:", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    by_policy = {name: side_summary(res["run"]["rows"], summarize) for name, res in results.items()}
    for label, key, f in SIDE_KEYS:
        cells = [fmt(f, by_policy[name].get(side, {}).get(key, math.nan)) for name in results for side in sides]
        lines.append("| " + " | ".join([label, *cells]) + " |")
    return lines
