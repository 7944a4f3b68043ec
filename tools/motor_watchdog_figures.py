"""Figures behind the supervisor's silent-motor and frozen-encoder rules (issue 48; rules R8, R9 of
runtime/src/safety_supervisor.cpp): lockstep trials of the chapter-6 harness (sim_hil.eval.trial) with the
host's view of every motor recorded each tick.

Per run: the runtime's fault, the longest run of NO_REPLY frames, the worst "still load" (the largest |PD
torque| of the last command held on a bit-identical encoder for longer than R9's time, as a share of R9's
torque threshold: 1.0 would trip) and when R9 trips. R9's numbers are read from runtime/include/t1rt/safety.hpp.

  tools/netns .venv/bin/python tools/motor_watchdog_figures.py stand walk getup:62 push:0 drop delay \\
      walk+untrained getup:3+baseline frozen:Left_Knee_Pitch@3 dead:Left_Ankle_Pitch@3
  --runtime PATH: another t1-runtime build (e.g. one without R9, so frozen runs are not cut short by it)
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

from messages import contract
from sim_hil import firmware as fw, launch
from sim_hil.eval import plans
from sim_hil.eval.trial import Controller, TrialSpec, run_trial, trial_lcm_url
from sim_hil.launch import ROOT
from sim_hil.sim import Simulator

POLICIES = {"": Controller("student", ROOT / "policies/student/student.safetensors"),
            "untrained": Controller("untrained", ROOT / "policies/student_untrained/student_untrained.safetensors"),
            "baseline": Controller("baseline", ROOT / "policies/getup_baseline/getup_baseline.safetensors",
                                   ROOT / "policies/joystick/joystick.safetensors")}
DT = 0.002


def r9_constants() -> tuple[float, float, int]:
    text = (ROOT / "runtime/include/t1rt/safety.hpp").read_text()
    get = lambda name: float(re.search(rf"{name} = ([0-9.]+)", text).group(1))   # noqa: E731
    return get("kFrozenEncoderTorqueFraction"), get("kFrozenEncoderMinTorqueNm"), int(get("kFrozenEncoderMaxCycles"))


def spec(name: str) -> TrialSpec:
    kind, _, arg = name.partition(":")
    walk = dict(command_vx_mps=plans.WALK_FORWARD_MPS, prepare_s=plans.STANDING_PREPARE_S)
    if kind in ("frozen", "dead"):            # frozen:JOINT@T / dead:JOINT@T while walking, 3 s logged after T
        joint, at = arg.split("@")
        return TrialSpec("flat", 0, "standing", float(at) + 3.0, faults=f"{kind}:joint={joint}@{at}", **walk)
    if kind == "push":
        return plans.push_specs(int(arg or 0) + 1, plans.PUSH_SECONDS, int(arg or 0))[-1]
    if kind == "getup":
        return TrialSpec("flat", int(arg or 62), f"fallen:{arg or 62}", plans.GETUP_SECONDS)
    return {"stand": TrialSpec("flat", 0, "standing", 20.0, prepare_s=plans.STANDING_PREPARE_S),
            "walk": TrialSpec("flat", 0, "standing", 20.0, **walk),
            "drop": TrialSpec("flat", 0, "standing", 10.0, faults="drop:rate=0.05@0", **walk),
            "delay": TrialSpec("flat", 0, "standing", 10.0, faults="delay:ticks=5@0", **walk),
            "prepare": TrialSpec("flat", 0, "standing", 8.0, prepare_s=5.0)}[kind]   # tests/test_dds.py's


def analyse(rows: list[np.ndarray], threshold: np.ndarray, width: int) -> str:
    q, dq, st, qd, kp, kd = np.split(np.array(rows), 6, axis=1)
    replied = (st[1:].astype(np.int64) & fw.STATUS_HOST_NO_REPLY) == 0
    # a row holds state k+1 and the command answering state k: the torque the runtime sees at state k+1
    tau = np.abs(kp * (qd - q) - kd * dq)[1:]
    still = (q[1:] == q[:-1]) & replied
    longest = 0
    run = np.zeros(q.shape[1], int)
    for miss in ~replied:
        run = np.where(miss, run + 1, 0)
        longest = max(longest, int(run.max()))
    load = np.lib.stride_tricks.sliding_window_view(np.where(still, tau, 0.0), width + 1, axis=0).min(axis=-1)
    k, j = np.unravel_index(np.argmax(load / threshold), load.shape)
    hot = load / threshold > 1.0
    trip = f"{(np.argmax(hot.any(axis=1)) + width + 1) * DT:.2f} s" if hot.any() else "never"
    return (f"longest NO_REPLY run {longest}; worst still load {load[k, j] / threshold[j]:.2f} of R9's threshold "
            f"({contract.JOINT_NAMES[j]} {load[k, j]:.1f} N·m at {(k + 1) * DT:.2f} s); R9 trips: {trip}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", help="stand | walk | getup:SEED | push:I | drop | delay | prepare | "
                    "frozen:JOINT@T | dead:JOINT@T, each optionally +untrained or +baseline")
    ap.add_argument("--runtime", type=Path, default=None)
    args = ap.parse_args()
    if args.runtime:
        launch.RUNTIME = args.runtime
    fraction, floor_nm, width = r9_constants()
    threshold = np.maximum(fraction * fw.TORQUE_LIMIT, floor_nm)
    rows: list[np.ndarray] = []
    orig = Simulator.tick

    def tick(sim: Simulator) -> None:
        orig(sim)
        c = sim.link.latest
        if c is not None:   # state k+1 as the host sees it, and the command answering state k
            b = sim.bus
            rows.append(np.concatenate([b.q, b.dq, b.status, c.q_des, c.kp, c.kd]))
    Simulator.tick = tick
    runs = []
    for name in args.runs:
        base, _, policy = name.partition("+")
        try:
            runs.append((name, spec(base), POLICIES[policy]))
        except (KeyError, ValueError) as exc:
            ap.error(f"run '{name}': not understood ({exc!r}); see the list under 'runs'")
    for name, trial, controller in runs:
        rows.clear()
        result = run_trial(trial, controller, trial_lcm_url(7))
        print(f"{name}: runtime fault [{result.runtime_faults or 'none'}]; {analyse(rows, threshold, width)}", flush=True)


if __name__ == "__main__":
    main()
