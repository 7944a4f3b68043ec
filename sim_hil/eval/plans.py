"""The four evaluation scenarios of the seed's chapter 6: which trials each runs, and how its trials are
summarised into the rows of its tables. Numbers a scenario fixes (speeds, impulses, finish line) live here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from common import scenarios as sim_scenarios
from common.effort import EFFORT_METRICS
from common.events import KNEEL_HIP_MIN_RAD, KNEEL_HOLD_S, KNEEL_KNEE_MIN_RAD
from common.push_test import (
    PUSH_ANGLE_SPREAD_RAD,
    PUSH_AT_S,
    PUSH_IMPULSE_NS,
    PUSH_IMPULSE_SPREAD,
    PUSH_TIME_SPREAD_S,
    push_draw,
)
from sim_hil.eval.trial import STEER_GAIN_PER_S, STEER_MAX_RPS, TrialResult, TrialSpec

# Standing spawns start in the default pose already: a short PREPARE hands the robot to the policy at once
# (the trial measures the policy; PREPARE itself holds the pose with the T1's stand-up gains, see
# messages/contract.json supervisor.prepare and tests/test_dds.py).
STANDING_PREPARE_S = 0.1
# getup: seeded fallen starts (common.model.fallen_state drops the robot from a random pose)
GETUP_TRIALS = 1000
GETUP_SECONDS = 12.0            # 2 s PREPARE ramp + 10 s to get up
# kneel: the same fallen starts for stage 1 (fallen → kneel, policies/getup_kneel): §4.8's gate in the kneeling
# posture within the batch evaluation's 8 s (training/ppo/kneel_report.py), held KNEEL_HOLD_S
KNEEL_TRIALS = 20
KNEEL_SECONDS = 10.0            # 2 s PREPARE ramp + 8 s to kneel
# push: 20 forward and 10 backward torso impulses (the draw: common/push_test.py)
PUSH_FORWARD, PUSH_BACKWARD = 20, 10
PUSH_SECONDS = 16.0
# walk: the joystick expert's in-the-loop targets (policies/joystick/CARD.md), standing starts on flat ground
WALK_SECONDS = 20.0
WALK_FORWARD_MPS = 0.4
WALK_YAW_RPS = 0.5
WALK_TARGETS = {"forward_m": 7.0, "stand_drift_m": 0.3, "turn_rad": 8.0}
WALK_STOP_AT = 0.5              # "walk, turn, stop": the command for this fraction of the trial, then zero
# wall: the three low walls at 0.4 m/s (Tables 6.1-6.2)
WALL_TRIALS = 5
WALL_COMMAND_MPS = 0.4
WALL_FINISH_BEHIND_LAST_M = 1.0  # finish line this far past the last wall's centre
WALL_SECONDS = 60.0             # 15 m at 0.4 m/s is 37.5 s; the rest is time to fall and get up
WALL_START_SPREAD_S = 1.0       # the seed picks when the command starts in this window [s]: each trial meets
                                # the walls at another point of its gait (deterministic lockstep otherwise)
# fig5.1: the seed's Fig. 5.1 (§5): one fallen start (seed 62), 0.4 m/s forward from the start, teacher and
# student side by side: trunk height, waist height, forward velocity
FIG51_SEED = 62
FIG51_COMMAND_MPS = 0.4
FIG51_SECONDS = 20.0            # 2 s PREPARE ramp, up to 10 s to get up, the rest walking
# puddle: seeded layouts (μ 0.4), constant forward command (Tables 6.3-6.4)
PUDDLE_TRIALS = 10
PUDDLE_COMMAND_MPS = 0.4
PUDDLE_SECONDS = 40.0           # 16 m of path (puddles lie on x 1-15 m) at 0.4 m/s
# walls and puddles: the courses run along +x; the operator steers the robot down them (trial.py,
# operator_yaw_rate; `--no-steer` for a constant stick)
COURSE_HEADING_RAD = 0.0
STEERED = (f"the operator steers down the course (yaw rate {STEER_GAIN_PER_S:g}/s × heading error, "
           f"≤ {STEER_MAX_RPS:g} rad/s, while upright) unless the command says --no-steer")


def wall_xs() -> list[float]:
    return [sim_scenarios.WALL_FIRST_X_M + i * sim_scenarios.WALL_SPACING_M for i in range(sim_scenarios.WALL_COUNT)]


def wall_finish_x() -> float:
    return wall_xs()[-1] + WALL_FINISH_BEHIND_LAST_M


def wall_segment_edges() -> list[float]:
    """Segment i (wall i) spans from halfway after wall i-1 to halfway after wall i (open ends)."""
    xs = wall_xs()
    mids = [(a + b) / 2 for a, b in zip(xs, xs[1:])]
    return [-math.inf, *mids, math.inf]


@dataclass(frozen=True)
class Plan:
    name: str
    sim_scenario: str
    default_trials: int
    default_seconds: float
    specs: Callable[[int, float, int], list[TrialSpec]]     # (trials, seconds, seed0) -> specs
    rows: Callable[[list[TrialResult]], dict[str, str]]     # one controller's trials -> table cells
    trial_cells: Callable[[TrialResult], dict[str, str]]    # one trial -> its cells in the per-trial table
    finish_x_m: float | None = None
    segment_edges_x: list[float] | None = None
    description: str = ""
    side_by_side: bool = False      # plots.png: one column per controller (else one overlaid column)
    seed0: int = 0                  # the first trial seed when --seed is not given


def _fmt(values, digits=2, unit="") -> str:
    v = np.asarray([x for x in values if x is not None and not (isinstance(x, float) and math.isnan(x))], float)
    if v.size == 0:
        return "n/a"
    return f"{v.mean():.{digits}f} ± {v.std():.{digits}f}{unit}" if v.size > 1 else f"{v[0]:.{digits}f}{unit}"


def _events(trials):
    return [r.events for r in trials if r.events is not None]


COMMON_ROWS = ("trials", "reached POLICY", "runtime faults")   # bookkeeping rows: no seed figure


def _common(trials: list[TrialResult]) -> dict[str, str]:
    ev = _events(trials)
    faults = sorted({r.runtime_faults for r in trials if r.runtime_faults})
    return {"trials": str(len(trials)),
            "reached POLICY": f"{len(ev)}/{len(trials)}",
            "runtime faults": "; ".join(faults) if faults else "none"}


# ---- getup -----------------------------------------------------------------------------------------------
def getup_specs(trials: int, seconds: float, seed0: int) -> list[TrialSpec]:
    return [TrialSpec("flat", seed0 + i, f"fallen:{seed0 + i}", seconds) for i in range(trials)]


def getup_rows(trials: list[TrialResult]) -> dict[str, str]:
    ev = _events(trials)
    ok = [e for e in ev if e.success]
    row = {"success rate": f"{len(ok)}/{len(trials)} ({100 * len(ok) / max(len(trials), 1):.0f} %)",
           "time to stand [s]": _fmt([e.time_to_stand_s for e in ok]),
           "getup attempts": _fmt([e.attempts for e in ev]),
           "through the kneel gate before standing": f"{sum(r.through_kneel_gate is True for r in trials)}/"
                                                     f"{sum(r.through_kneel_gate is not None for r in trials)} stood"}
    for key, label, _ in EFFORT_METRICS:
        row[label] = _fmt([r.effort.get(key) for r in trials if r.effort], 1)
    return {**row, **_common(trials)}


# ---- kneel -----------------------------------------------------------------------------------------------
def kneel_rows(trials: list[TrialResult]) -> dict[str, str]:
    """Stage 1's figures: the share that met the gate in the kneeling posture, in all and by how it lay, and of
    those the share that held it KNEEL_HOLD_S."""
    def met(sub):
        return f"{sum(r.kneel_hold_s > 0 for r in sub)}/{len(sub)}"
    kneeled = [r for r in trials if r.kneel_hold_s > 0]
    return {"the gate in the kneeling posture": met(trials),
            "… face down": met([r for r in trials if r.lying == "face_down"]),
            "… on the back": met([r for r in trials if r.lying == "on_back"]),
            f"… held ≥ {KNEEL_HOLD_S:g} s (of those)": f"{sum(r.kneel_hold_s >= KNEEL_HOLD_S for r in kneeled)}/"
                                                    f"{len(kneeled)}",
            "time to the gate [s]": _fmt([r.kneel_time_s for r in kneeled]), **_common(trials)}


def _kneel_cells(r: TrialResult) -> dict[str, str]:
    return {"lying": r.lying or "—", "met the gate at [s]": _n(r.kneel_time_s),
            "longest hold [s]": _n(r.kneel_hold_s)}


# ---- push ------------------------------------------------------------------------------------------------
def push_fault(p, at_s: float | None = None) -> str:
    """A push draw as the sim's --faults spec, at its own time or at at_s [s]."""
    return (f"push:x={p.impulse_ns * math.cos(p.angle_rad):.2f},y={p.impulse_ns * math.sin(p.angle_rad):.2f},"
            f"z=0@{p.at_s if at_s is None else at_s:.3f}")


def push_specs(trials: int, seconds: float, seed0: int) -> list[TrialSpec]:
    out = []
    for i in range(trials):
        p = push_draw(i, seed0 + i)
        out.append(TrialSpec("flat", seed0 + i, "standing", seconds, prepare_s=STANDING_PREPARE_S,
                             faults=push_fault(p),
                             tag="forward" if p.forward else "backward"))
    return out


def push_rows(trials: list[TrialResult]) -> dict[str, str]:
    row: dict[str, str] = {}
    for direction in ("forward", "backward"):
        sub = [r for r in trials if r.spec.tag == direction]
        ev = _events(sub)
        att = np.asarray([e.attempts for e in ev], float)
        stats = (f"{att.mean():.2f} / {att.max():.0f} / {att.min():.0f} / {att.std():.2f}" if att.size else "n/a")
        row[f"{direction}: trials"] = str(len(sub))
        row[f"{direction}: attempts mean / max / min / std"] = stats
        row[f"{direction}: fell"] = f"{sum(e.falls > 0 for e in ev)}/{len(sub)}"
        row[f"{direction}: up at the end"] = f"{sum(e.success for e in ev)}/{len(sub)}"
        row[f"{direction}: ran to stabilise"] = f"{sum(r.ran_to_stabilise for r in sub)}/{len(sub)}"
    return {**row, **_common(trials)}


# ---- walk -------------------------------------------------------------------------------------------------
WALK_CONDITIONS = (   # tag, vx [m/s], yaw rate [rad/s], clock, stops (zero command after WALK_STOP_AT)
    ("forward", WALK_FORWARD_MPS, 0.0, "lockstep", False), ("stand", 0.0, 0.0, "lockstep", False),
    ("turn", 0.0, WALK_YAW_RPS, "lockstep", False), ("forward realtime", WALK_FORWARD_MPS, 0.0, "realtime", False),
    # not a card target: stopping from a walk (a joystick expert once fell after its stop in make demo)
    ("walk, turn, stop", WALK_FORWARD_MPS, WALK_YAW_RPS, "lockstep", True))


def walk_specs(trials: int, seconds: float, seed0: int) -> list[TrialSpec]:
    """Each trial index runs every condition once (--trials N: N of each)."""
    return [TrialSpec("flat", seed0 + i, "standing", seconds, command_vx_mps=vx, command_yaw_rps=yaw,
                      command_stop_s=WALK_STOP_AT * seconds if stops else None,
                      clock=clock, prepare_s=STANDING_PREPARE_S, tag=tag)
            for i in range(trials) for tag, vx, yaw, clock, stops in WALK_CONDITIONS]


def walk_rows(trials: list[TrialResult]) -> dict[str, str]:
    row: dict[str, str] = {}
    for tag, *_ in WALK_CONDITIONS:
        sub = [r for r in trials if r.spec.tag == tag]
        ev = _events(sub)
        row[f"{tag}: fell"] = f"{sum(e.falls > 0 for e in ev)}/{len(sub)}"
        row[f"{tag}: distance from POLICY start [m]"] = _fmt([r.drift_m for r in sub])
        row[f"{tag}: heading turned [rad]"] = _fmt([r.yaw_turned_rad for r in sub])
        if any(r.spec.command_stop_s is not None for r in sub):
            row[f"{tag}: distance after the stop [m]"] = _fmt([r.after_stop_m for r in sub])
    return {**row, **_common(trials)}


# ---- wall ------------------------------------------------------------------------------------------------
def wall_specs(trials: int, seconds: float, seed0: int) -> list[TrialSpec]:
    return [TrialSpec("walls", seed0 + i, "standing", seconds, command_vx_mps=WALL_COMMAND_MPS,
                      steer_heading_rad=COURSE_HEADING_RAD,
                      command_start_s=STANDING_PREPARE_S
                      + np.random.default_rng(seed0 + i).uniform(0.0, WALL_START_SPREAD_S),
                      prepare_s=STANDING_PREPARE_S) for i in range(trials)]


def _course_time_s(r: TrialResult) -> float:
    """From the first commanded tick under the policy to the finish line [s]."""
    return r.finish_time_s - max(r.policy_start_s, r.spec.command_start_s)


def wall_rows(trials: list[TrialResult]) -> dict[str, str]:
    done = [r for r in trials if not math.isnan(r.finish_time_s)]
    row = {"completion time [s]": _fmt([_course_time_s(r) for r in done], 1),
           "DNF": f"{len(trials) - len(done)}/{len(trials)}",
           "distance [m]": _fmt([r.final_x_m for r in trials], 1)}
    attempts = [r.segment_attempts for r in trials if r.segment_attempts]
    row["getup attempts per wall"] = _fmt([a for per_wall in attempts for a in per_wall])
    row["getup attempts per trial"] = _fmt([sum(per_wall) for per_wall in attempts])
    for i in range(len(wall_xs())):
        row[f"wall {i + 1}: getup attempts"] = _fmt([r.segment_attempts[i] for r in trials if r.segment_attempts])
        row[f"wall {i + 1}: falls"] = _fmt([r.segment_falls[i] for r in trials if r.segment_falls])
    return {**row, **_common(trials)}


# ---- fig5.1 ----------------------------------------------------------------------------------------------
def fig51_specs(trials: int, seconds: float, seed0: int) -> list[TrialSpec]:
    return [TrialSpec("flat", seed0 + i, f"fallen:{seed0 + i}", seconds, command_vx_mps=FIG51_COMMAND_MPS)
            for i in range(trials)]


def _vx_once_standing(r: TrialResult) -> float:
    """Mean forward velocity [m/s] from the stand-up (POLICY start + time to stand) to the end; nan if never up."""
    if r.events is None or math.isnan(r.events.time_to_stand_s):
        return math.nan
    t, vx = np.asarray(r.plot["t"]), np.asarray(r.plot["vx"])
    after = vx[t >= r.policy_start_s + r.events.time_to_stand_s]
    return float(after.mean()) if after.size else math.nan


def fig51_rows(trials: list[TrialResult]) -> dict[str, str]:
    ev = _events(trials)
    return {"stood up": f"{sum(e.success for e in ev)}/{len(trials)}",
            "time to stand [s]": _fmt([e.time_to_stand_s for e in ev]),
            "getup attempts": _fmt([e.attempts for e in ev]),
            "forward velocity once standing [m/s]": _fmt([_vx_once_standing(r) for r in trials]),
            "distance [m]": _fmt([r.final_x_m for r in trials], 1),
            **_common(trials)}


# ---- puddle ----------------------------------------------------------------------------------------------
def puddle_specs(trials: int, seconds: float, seed0: int) -> list[TrialSpec]:
    return [TrialSpec("puddles", seed0 + i, "standing", seconds, command_vx_mps=PUDDLE_COMMAND_MPS,
                      steer_heading_rad=COURSE_HEADING_RAD, prepare_s=STANDING_PREPARE_S) for i in range(trials)]


def puddle_rows(trials: list[TrialResult]) -> dict[str, str]:
    ev = _events(trials)
    return {"slips per trial": _fmt([r.slips for r in trials]),
            "trials with a slip": f"{sum(r.slips > 0 for r in trials)}/{len(trials)}",
            "falls per trial": _fmt([e.falls for e in ev]),
            "getup attempts per trial": _fmt([e.attempts for e in ev]),
            "up at the end": f"{sum(e.success for e in ev)}/{len(trials)}",
            "distance [m]": _fmt([r.final_x_m for r in trials], 1),
            **_common(trials)}


# ---- per trial (the report's table beside the seed's per-trial tables) -----------------------------------
def _n(value, digits=1) -> str:
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}f}"


def _yes(flag) -> str:
    return "—" if flag is None else ("yes" if flag else "no")


def _getup_cells(r: TrialResult) -> dict[str, str]:   # events are None when POLICY was never reached
    e = r.events
    return {"stood up": _yes(e and e.success), "time to stand [s]": _n(e.time_to_stand_s if e else None, 2),
            "getup attempts": str(e.attempts) if e else "—"}


def _push_cells(r: TrialResult) -> dict[str, str]:
    e = r.events
    return {"direction": r.spec.tag, "fell": _yes(e and e.falls > 0), "getup attempts": str(e.attempts) if e else "—",
            "up at the end": _yes(e and e.success), "ran to stabilise": _yes(r.ran_to_stabilise)}


def _walk_cells(r: TrialResult) -> dict[str, str]:
    return {"condition": r.spec.tag, "fell": _yes(r.events and r.events.falls > 0),
            "distance [m]": _n(r.drift_m, 2), "heading turned [rad]": _n(r.yaw_turned_rad, 2)}


def _wall_cells(r: TrialResult) -> dict[str, str]:
    done = not math.isnan(r.finish_time_s)
    return {"completion time [s]": _n(_course_time_s(r)) if done else "DNF",
            "getup attempts (total)": str(sum(r.segment_attempts)) if r.segment_attempts else "—",
            "per wall": ", ".join(map(str, r.segment_attempts)) or "—", "distance [m]": _n(r.final_x_m)}


def _puddle_cells(r: TrialResult) -> dict[str, str]:
    e = r.events
    return {"slips": str(r.slips), "getup attempts": str(e.attempts) if e else "—",
            "up at the end": _yes(e and e.success), "distance [m]": _n(r.final_x_m)}


def _fig51_cells(r: TrialResult) -> dict[str, str]:
    return {**_getup_cells(r), "forward velocity once standing [m/s]": _n(_vx_once_standing(r), 2),
            "distance [m]": _n(r.final_x_m)}


PLANS = {
    "getup": Plan("getup", "flat", GETUP_TRIALS, GETUP_SECONDS, getup_specs, getup_rows, _getup_cells,
                  description="seeded fallen starts on flat ground, no command (Table 4.3 metrics)"),
    "kneel": Plan("kneel", "flat", KNEEL_TRIALS, KNEEL_SECONDS, getup_specs, kneel_rows, _kneel_cells,
                  description="stage 1: seeded fallen starts on flat ground, no command; §4.8's gate in the kneeling "
                              f"posture (both knees ≥ {KNEEL_KNEE_MIN_RAD:g} rad, "
                              f"hips ≥ {KNEEL_HIP_MIN_RAD:g} rad) and "
                              f"its hold ≥ {KNEEL_HOLD_S:g} s"),
    "push": Plan("push", "flat", PUSH_FORWARD + PUSH_BACKWARD, PUSH_SECONDS, push_specs, push_rows, _push_cells,
                 description=f"standing, no command, one torso impulse of ±{PUSH_IMPULSE_NS:g} N·s "
                             f"(seeded: ±{PUSH_IMPULSE_SPREAD:.0%}, "
                             f"±{math.degrees(PUSH_ANGLE_SPREAD_RAD):.0f}° off x) at "
                             f"t = {PUSH_AT_S:g}-{PUSH_AT_S + PUSH_TIME_SPREAD_S:g} s ({PUSH_FORWARD} forward, "
                             f"{PUSH_BACKWARD} backward)"),
    "walk": Plan("walk", "flat", 1, WALK_SECONDS, walk_specs, walk_rows, _walk_cells,
                 description=f"standing starts, {WALK_SECONDS:g} s each: {WALK_FORWARD_MPS} m/s forward, zero "
                             f"command, {WALK_YAW_RPS} rad/s yaw (lockstep), {WALK_FORWARD_MPS} m/s in realtime, "
                             f"{WALK_FORWARD_MPS} m/s with {WALK_YAW_RPS} rad/s, "
                             f"zero command from {WALK_STOP_AT:.0%} of the trial "
                             f"(lockstep); targets: forward ≥ {WALK_TARGETS['forward_m']:g} m, stand drift ≤ "
                             f"{WALK_TARGETS['stand_drift_m']:g} m, turn ≥ {WALK_TARGETS['turn_rad']:g} rad, "
                             "no fall"),
    "wall": Plan("wall", "walls", WALL_TRIALS, WALL_SECONDS, wall_specs, wall_rows, _wall_cells,
                 finish_x_m=wall_finish_x(), segment_edges_x=wall_segment_edges(),
                 description=f"three 0.2 m walls at x = {', '.join(f'{x:g}' for x in wall_xs())} m, "
                             f"{WALL_COMMAND_MPS} m/s forward from a seeded start within {WALL_START_SPREAD_S:g} s; "
                             f"finish line x = {wall_finish_x():g} m; {STEERED}"),
    "fig5.1": Plan("fig5.1", "flat", 1, FIG51_SECONDS, fig51_specs, fig51_rows, _fig51_cells, side_by_side=True,
                   seed0=FIG51_SEED,
                   description=f"the seed's Fig. 5.1: fallen start (seed {FIG51_SEED}), {FIG51_COMMAND_MPS} m/s "
                               "forward from the start; teacher (--teacher) and student side by side"),
    "puddle": Plan("puddle", "puddles", PUDDLE_TRIALS, PUDDLE_SECONDS, puddle_specs, puddle_rows, _puddle_cells,
                   description=f"seeded puddle layouts (μ {sim_scenarios.PUDDLE_FRICTION}), "
                               f"{PUDDLE_COMMAND_MPS} m/s forward; {STEERED}"),
}
