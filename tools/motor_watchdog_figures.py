"""Figures behind the supervisor's motor rules R8 (silent motor), R9 (frozen encoder) and R10 (impossible
reading) of runtime/src/safety_supervisor.cpp: lockstep trials of the chapter-6 harness (sim_hil.eval.trial)
with the host's view of every motor and the trunk's angular rate recorded each tick.

Per run: the runtime's fault and how long after the injected fault it came, the longest run of NO_REPLY
frames, the worst "still load" R9 could see (the largest |PD torque| held on a bit-identical encoder, away
from the stops, while the body turned and the limbs moved, for longer than R9's time, as a share of R9's
torque threshold: 1.0 would trip), the longest such evidence run at several torque thresholds, the filtered
motion signals, and R10's margins (fastest step as a share of its bound, furthest
reading past a range end). The rules' numbers are read from runtime/include/t1rt/safety.hpp.

  tools/netns .venv/bin/python tools/motor_watchdog_figures.py stand walk getup:62 push:0 drop delay \\
      getup:3+knockdown frozen:Left_Knee_Pitch@3 frozen-getup:Left_Knee_Pitch:62 frozen-push:Left_Knee_Pitch:0
  --matrix: R9's detection matrix (frozen while walking, during getups, during pushes; leg joints)
  --runtime PATH: another t1-runtime build (e.g. one without R9/R10, so runs are not cut short by them)
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

from messages import contract
from sim_hil import firmware as fw
from sim_hil import launch
from sim_hil.eval import plans
from sim_hil.eval.trial import Controller, TrialSpec, run_trial, trial_lcm_url
from sim_hil.launch import ROOT
from sim_hil.sim import Simulator

POLICIES = {"": Controller("student", ROOT / "policies/student/student.safetensors"),
            "untrained": Controller("untrained", ROOT / "policies/student_untrained/student_untrained.safetensors"),
            "knockdown": Controller("getup_knockdown", ROOT / "policies/getup_knockdown/getup_knockdown.safetensors"),
            "baseline": Controller("baseline", ROOT / "policies/getup_baseline/getup_baseline.safetensors",
                                   ROOT / "policies/joystick/joystick.safetensors")}
DT = 0.002
LEG_JOINTS = [n for n in contract.JOINT_NAMES if any(k in n for k in ("Hip_Pitch", "Hip_Roll", "Knee", "Ankle"))]
GETUP_FREEZE_S = 3.0          # 1 s into the rise: POLICY starts after the 2 s PREPARE from a fallen start
AFTER_FAULT_S = 2.5           # logged after an injected fault
SWEEP_FRACTIONS = (0.45, 0.5, 0.55, 0.6, 0.65)   # R9 torque fractions the evidence runs are also counted at


def constants() -> dict[str, float]:
    text = (ROOT / "runtime/include/t1rt/safety.hpp").read_text()
    names = ("kFrozenEncoderTorqueFraction", "kFrozenEncoderMinTorqueNm", "kFrozenEncoderMaxCycles",
             "kBodyMotionTimeConstantS", "kBodyMotionMinRateRadS", "kJointMotionMinSpeedRadS",
             "kFrozenEncoderStopMarginRad", "kImpossibleRangeMarginRad", "kImpossibleSpeedFactor")
    return {n: float(re.search(rf"{n} = ([0-9.]+)", text).group(1)) for n in names}


def push_faults(index: int) -> tuple[str, float]:
    p = plans.push_draw(index, index)
    return plans.push_fault(p), p.at_s


def spec(name: str) -> tuple[TrialSpec, float | None]:
    """The trial of a run name, and when its injected motor fault starts [s] (None: none)."""
    kind, _, arg = name.partition(":")
    walk = dict(command_vx_mps=plans.WALK_FORWARD_MPS, prepare_s=plans.STANDING_PREPARE_S)
    if kind in ("frozen", "dead"):            # frozen:JOINT@T / dead:JOINT@T while walking
        joint, at = arg.split("@")
        return TrialSpec("flat", 0, "standing", float(at) + AFTER_FAULT_S, faults=f"{kind}:joint={joint}@{at}",
                         **walk), float(at)
    if kind == "frozen-getup":                # frozen-getup:JOINT:SEED, 1 s into the rise
        joint, seed = arg.split(":")
        return TrialSpec("flat", int(seed), f"fallen:{seed}", GETUP_FREEZE_S + AFTER_FAULT_S,
                         faults=f"frozen:joint={joint}@{GETUP_FREEZE_S}"), GETUP_FREEZE_S
    if kind == "frozen-push":                 # frozen-push:JOINT:I, frozen as the push test's push I lands
        joint, index = arg.split(":")
        push, at = push_faults(int(index))
        return TrialSpec("flat", int(index), "standing", at + AFTER_FAULT_S, prepare_s=plans.STANDING_PREPARE_S,
                         faults=f"{push};frozen:joint={joint}@{at:.3f}"), at
    if kind == "push":
        return plans.push_specs(int(arg or 0) + 1, plans.PUSH_SECONDS, int(arg or 0))[-1], None
    if kind == "getup":
        return TrialSpec("flat", int(arg or 62), f"fallen:{arg or 62}", plans.GETUP_SECONDS), None
    return {"stand": TrialSpec("flat", 0, "standing", 20.0, prepare_s=plans.STANDING_PREPARE_S),
            "walk": TrialSpec("flat", 0, "standing", 20.0, **walk),
            "drop": TrialSpec("flat", 0, "standing", 10.0, faults="drop:rate=0.05@0", **walk),
            "delay": TrialSpec("flat", 0, "standing", 10.0, faults="delay:ticks=5@0", **walk),
            "prepare": TrialSpec("flat", 0, "standing", 8.0, prepare_s=5.0)}[kind], None   # tests/test_dds.py's


def low_pass(x: np.ndarray, time_constant_s: float) -> np.ndarray:
    out, gain, y = np.empty_like(x), DT / time_constant_s, 0.0
    for k, v in enumerate(x):
        y += gain * (v - y)
        out[k] = y
    return out


def analyse(rows: list[np.ndarray], c: dict[str, float], fault_at: float | None) -> str:
    q, dq, st, qd, kp, kd, mode = (np.array(rows)[:, i * 23:(i + 1) * 23] for i in range(7))
    gyro = np.array(rows)[:, 7 * 23:7 * 23 + 3]
    threshold = np.maximum(c["kFrozenEncoderTorqueFraction"] * fw.TORQUE_LIMIT, c["kFrozenEncoderMinTorqueNm"])
    width = int(c["kFrozenEncoderMaxCycles"])
    replied = (st[1:].astype(np.int64) & fw.STATUS_HOST_NO_REPLY) == 0
    # a row holds state k+1 and the command answering state k: the torque the runtime sees at state k+1
    tau = np.abs(kp * (qd - q) - kd * dq)[1:]
    body = low_pass(np.linalg.norm(gyro, axis=1), c["kBodyMotionTimeConstantS"])[1:]
    limbs = low_pass(np.abs(dq).mean(axis=1), c["kBodyMotionTimeConstantS"])[1:]
    margin = c["kFrozenEncoderStopMarginRad"]
    off_stops = (q[1:] > fw.Q_MIN + margin) & (q[1:] < fw.Q_MAX - margin)
    moving = (body > c["kBodyMotionMinRateRadS"]) & (limbs > c["kJointMotionMinSpeedRadS"])
    evidence = (q[1:] == q[:-1]) & replied & off_stops & moving[:, None]
    longest, run = 0, np.zeros(q.shape[1], int)
    for miss in ~replied:
        run = np.where(miss, run + 1, 0)
        longest = max(longest, int(run.max()))
    load = np.lib.stride_tricks.sliding_window_view(np.where(evidence, tau, 0.0), width + 1, axis=0).min(axis=-1)
    k, j = np.unravel_index(np.argmax(load / threshold), load.shape)
    runs = []          # the longest run of replies with R9's evidence, at this threshold and at others
    for fraction in SWEEP_FRACTIONS:
        over = evidence & (tau > np.maximum(fraction * fw.TORQUE_LIMIT, c["kFrozenEncoderMinTorqueNm"]))
        run, best = np.zeros(q.shape[1], int), 0
        for row in over:
            run = np.where(row, run + 1, 0)
            best = max(best, int(run.max()))
        runs.append(f"{fraction:g}: {best}")
    both = replied & ((st[:-1].astype(np.int64) & fw.STATUS_HOST_NO_REPLY) == 0)
    speed = np.where(both, np.abs(np.diff(q, axis=0)) / DT, 0.0) / (c["kImpossibleSpeedFactor"] * fw.V_RANGE)
    past = np.maximum(fw.Q_MIN - q, q - fw.Q_MAX).max()
    faulted = np.flatnonzero(mode[:, 0] == 4)     # joint_command_t.MODE_FAULT
    when = "" if not faulted.size or fault_at is None else f" {faulted[0] * DT + DT - fault_at:.2f} s after the fault"
    return (f"longest NO_REPLY run {longest}; worst still load with evidence {load[k, j] / threshold[j]:.2f} of R9's "
            f"threshold ({contract.JOINT_NAMES[j]} at {(k + 1) * DT:.2f} s); longest evidence run by torque "
            f"fraction ({', '.join(runs)}; more than {width} trips); filtered body rate max {body.max():.2f}, last "
            f"5 s max {body[-2500:].max():.3f} rad/s, limb speed last 5 s max {limbs[-2500:].max():.3f} rad/s; "
            "R10: fastest step "
            f"{speed.max():.2f} of its bound, furthest {past:+.3f} rad past a range end (margin "
            f"{c['kImpossibleRangeMarginRad']:g});{when}")


def matrix() -> list[str]:
    """R9's detection matrix: each leg joint frozen while walking (two moments of the gait), 1 s into a
    getup (two fallen seeds, the student and the getup expert) and as a push-test push lands (two pushes)."""
    runs = []
    for joint in LEG_JOINTS:
        runs += [f"frozen:{joint}@{at}" for at in (3.0, 3.37)]
        runs += [f"frozen-getup:{joint}:{seed}{policy}" for seed in (62, 3) for policy in ("", "+knockdown")]
        runs += [f"frozen-push:{joint}:{index}" for index in (0, 2)]
    return runs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="*", help="stand | walk | getup:SEED | push:I | drop | delay | prepare | "
                    "frozen:JOINT@T | dead:JOINT@T | frozen-getup:JOINT:SEED | frozen-push:JOINT:I, each "
                    "optionally +untrained, +knockdown or +baseline")
    ap.add_argument("--matrix", action="store_true", help="R9's detection matrix (see matrix())")
    ap.add_argument("--runtime", type=Path, default=None)
    args = ap.parse_args()
    if args.runtime:
        launch.RUNTIME = args.runtime
    names = args.runs + (matrix() if args.matrix else [])
    if not names:
        ap.error("name runs, or --matrix")
    c = constants()
    rows: list[np.ndarray] = []
    orig = Simulator.tick

    def tick(sim: Simulator) -> None:
        orig(sim)
        cmd = sim.link.latest
        if cmd is not None:   # state k+1 as the host sees it, and the command answering state k
            b = sim.bus
            rows.append(np.concatenate([b.q, b.dq, b.status, cmd.q_des, cmd.kp, cmd.kd,
                                        np.full(23, cmd.mode), sim.data.qvel[3:6]]))   # trunk rate, body frame
    Simulator.tick = tick
    runs = []
    for name in names:
        base, _, policy = name.partition("+")
        try:
            runs.append((name, *spec(base), POLICIES[policy]))
        except (KeyError, ValueError) as exc:
            ap.error(f"run '{name}': not understood ({exc!r}); see the list under 'runs'")
    tripped, late = 0, []
    for name, trial, fault_at, controller in runs:
        rows.clear()
        result = run_trial(trial, controller, trial_lcm_url(7))
        line = analyse(rows, c, fault_at)
        print(f"{name}: runtime fault [{result.runtime_faults or 'none'}]; {line}", flush=True)
        if fault_at is not None:
            m = re.search(r" ([0-9.]+) s after the fault", line)
            tripped += bool(m and float(m.group(1)) <= 1.0)
            late += [name] if not (m and float(m.group(1)) <= 1.0) else []
    injected = sum(f is not None for _, _, f, _ in runs)
    if injected:
        print(f"tripped within 1 s: {tripped} of {injected}; not: {', '.join(late) or 'none'}")


if __name__ == "__main__":
    main()
