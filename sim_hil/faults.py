"""Fault injection for the simulated T1: parse `--faults` specs and answer, per tick, what is active.

Spec grammar (several faults separated by ';'):

    KIND[:key=value[,key=value...]][@START[-END]]      START/END in sim seconds; no END = until the end

    drop:rate=0.2@1.0          each CAN frame (command and reply) is lost with probability 0.2
    delay:ticks=3@2.0-4.0      CAN command frames reach the motors 3 bus cycles (2 ms each) late
    dead:joint=Left_Knee_Pitch@5   that motor stops: no torque, no reply frames (joint name or index)
    frozen:joint=14@3          that motor's encoder sticks at its value at START: q holds, dq (differentiated
                               from it) reads 0, the motor's PD law and soft stop act on the stuck reading, and
                               tau_est stays the torque the motor applies (its current); IMU and other motors as ever
    imu_noise:gyro=0.05,accel=0.5,quat=0.01@0   zero-mean Gaussian noise, std in rad/s, m/s², quat units
    imu_bias:gyro=0.02,accel=0.3@0              constant offset added to every axis [rad/s, m/s²]
    push:x=30,y=0,z=0@2.0      one torso impulse [N·s] in the world frame, applied over one physics step
    load:z=-300@0-8            a constant force [N] on the torso in the world frame (someone holding it down)
    press:joint=Left_Elbow_Yaw,tau=25@1   a constant outside torque [N·m] on that joint about its axis (a hand
                               holding the limb against its stop)

Random draws (drops, noise) come from one numpy Generator seeded by --seed, so lockstep runs with the same
seed stay bit-identical with faults on.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from messages import contract

KINDS = {
    "drop": {"rate"},
    "delay": {"ticks"},
    "dead": {"joint"},
    "frozen": {"joint"},
    "imu_noise": {"gyro", "accel", "quat"},
    "imu_bias": {"gyro", "accel"},
    "push": {"x", "y", "z"},
    "load": {"x", "y", "z"},
    "press": {"joint", "tau"},
}


class FaultSpecError(ValueError):
    """A --faults spec that cannot be understood; the message names the offending part."""


@dataclass(frozen=True)
class Fault:
    kind: str
    params: dict = field(default_factory=dict)
    start_s: float = 0.0
    end_s: float = math.inf

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s < self.end_s

    def spec(self) -> str:
        args = ",".join(f"{k}={v}" for k, v in sorted(self.params.items()))
        window = f"@{self.start_s:g}" + ("" if math.isinf(self.end_s) else f"-{self.end_s:g}")
        return f"{self.kind}{':' + args if args else ''}{window}"


def _parse_joint(value: str, part: str) -> int:
    if value.lstrip("-").isdigit():
        idx = int(value)
        if not 0 <= idx < contract.NUM_JOINTS:
            raise FaultSpecError(f"fault '{part}': joint index {idx} outside 0..{contract.NUM_JOINTS - 1}")
        return idx
    if value not in contract.JOINT_NAMES:
        raise FaultSpecError(f"fault '{part}': unknown joint '{value}' (names as in messages/contract.json)")
    return contract.joint_index(value)


def _parse_number(key: str, value: str, part: str) -> float:
    try:
        number = float(value)
    except ValueError:
        raise FaultSpecError(f"fault '{part}': {key}={value!r} is not a number") from None
    if not math.isfinite(number):
        raise FaultSpecError(f"fault '{part}': {key} must be finite")
    return number


def _parse_one(part: str) -> Fault:
    body, _, window = part.partition("@")
    kind, _, args = body.partition(":")
    kind = kind.strip()
    if kind not in KINDS:
        raise FaultSpecError(f"fault '{part}': unknown kind '{kind}' (known: {', '.join(sorted(KINDS))})")
    params: dict = {}
    for item in filter(None, (a.strip() for a in args.split(","))):
        key, eq, value = item.partition("=")
        if not eq:
            raise FaultSpecError(f"fault '{part}': '{item}' is not key=value")
        if key not in KINDS[kind]:
            raise FaultSpecError(f"fault '{part}': '{key}' is not a parameter of {kind} "
                                 f"(allowed: {', '.join(sorted(KINDS[kind]))})")
        params[key] = _parse_joint(value, part) if key == "joint" else _parse_number(key, value, part)
    if kind in ("dead", "frozen", "press") and "joint" not in params:
        raise FaultSpecError(f"fault '{part}': {kind} needs joint=NAME|INDEX")
    if kind == "press" and "tau" not in params:
        raise FaultSpecError(f"fault '{part}': press needs tau=N·m")
    if kind == "drop" and not 0.0 <= params.get("rate", -1.0) <= 1.0:
        raise FaultSpecError(f"fault '{part}': drop needs rate in [0, 1]")
    if kind == "delay" and (params.get("ticks", 0) < 1 or params["ticks"] != int(params["ticks"])):
        raise FaultSpecError(f"fault '{part}': delay needs an integer ticks >= 1")
    if kind in ("imu_noise", "imu_bias", "push", "load") and not params:
        raise FaultSpecError(f"fault '{part}': {kind} needs at least one of {', '.join(sorted(KINDS[kind]))}")
    if kind == "imu_noise" and any(v < 0 for v in params.values()):
        raise FaultSpecError(f"fault '{part}': noise standard deviations must be >= 0")
    start, end = 0.0, math.inf
    if window:
        first, dash, last = window.partition("-")
        start = _parse_number("start", first, part)
        if dash:
            end = _parse_number("end", last, part)
        if start < 0 or end <= start:
            raise FaultSpecError(f"fault '{part}': time window must satisfy 0 <= START < END")
    return Fault(kind, params, start, end)


def parse_faults(spec: str | None) -> list[Fault]:
    """Parse a --faults string; raises FaultSpecError naming the bad part."""
    if not spec:
        return []
    return [_parse_one(p.strip()) for p in spec.split(";") if p.strip()]


class FaultSchedule:
    """What is active at sim time t. Pushes fire once, on the first tick at or after their start."""

    def __init__(self, faults: list[Fault]):
        self.faults = faults
        self._pushes_done: set[int] = set()

    def active(self, t_s: float, kind: str) -> list[Fault]:
        return [f for f in self.faults if f.kind == kind and f.active(t_s)]

    def drop_rate(self, t_s: float) -> float:
        rates = [f.params["rate"] for f in self.active(t_s, "drop")]
        return max(rates, default=0.0)

    def delay_ticks(self, t_s: float) -> int:
        return int(max((f.params["ticks"] for f in self.active(t_s, "delay")), default=0))

    def dead_joints(self, t_s: float) -> set[int]:
        return {f.params["joint"] for f in self.active(t_s, "dead")}

    def frozen_joints(self, t_s: float) -> set[int]:
        return {f.params["joint"] for f in self.active(t_s, "frozen")}

    def trunk_load(self, t_s: float) -> tuple[float, float, float] | None:
        """The sum of the active `load` forces [N], world frame; None when there is none."""
        loads = self.active(t_s, "load")
        if not loads:
            return None
        return tuple(sum(f.params.get(k, 0.0) for f in loads) for k in ("x", "y", "z"))

    def joint_presses(self, t_s: float) -> dict[int, float]:
        """joint index -> the sum of the active `press` torques on it [N·m]."""
        out: dict[int, float] = {}
        for f in self.active(t_s, "press"):
            out[f.params["joint"]] = out.get(f.params["joint"], 0.0) + f.params["tau"]
        return out

    def imu_noise(self, t_s: float) -> dict:
        out = {"gyro": 0.0, "accel": 0.0, "quat": 0.0}
        for f in self.active(t_s, "imu_noise"):
            for k, v in f.params.items():
                out[k] = max(out[k], v)
        return out

    def imu_bias(self, t_s: float) -> dict:
        out = {"gyro": 0.0, "accel": 0.0}
        for f in self.active(t_s, "imu_bias"):
            for k, v in f.params.items():
                out[k] += v
        return out

    def needs_python_tick(self, t_s: float, t_end_s: float) -> bool:
        """Whether a fault the C++ lockstep tick does not model acts in the tick [t_s, t_end_s]: IMU noise or
        bias (read at its start), a frozen encoder (read at every substep and at its end), a push due, a load
        or a press (dead motors, lost and delayed frames it does)."""
        for i, f in enumerate(self.faults):
            if f.kind in ("imu_noise", "imu_bias") and f.active(t_s):
                return True
            if f.kind in ("load", "press") and f.start_s <= t_end_s and t_s < f.end_s:
                return True
            if f.kind == "frozen" and f.start_s <= t_end_s and t_s < f.end_s:
                return True
            if f.kind == "push" and i not in self._pushes_done and t_end_s >= f.start_s:
                return True
        return False

    def next_change_s(self, t_s: float) -> float:
        """The first sim time after t_s at which a fault starts or ends (inf: none): until then every query
        answers as at t_s, so the simulator may run the ticks before it in one batch."""
        edges = [e for f in self.faults for e in (f.start_s, f.end_s) if e > t_s]
        return min(edges, default=math.inf)

    def due_pushes(self, t_s: float) -> list[tuple[float, float, float]]:
        """Impulses [N·s] to apply now (each once)."""
        due = []
        for i, f in enumerate(self.faults):
            if f.kind == "push" and i not in self._pushes_done and t_s >= f.start_s:
                self._pushes_done.add(i)
                due.append((f.params.get("x", 0.0), f.params.get("y", 0.0), f.params.get("z", 0.0)))
        return due

    def describe(self, t_s: float) -> str:
        return ",".join(f.spec() for f in self.faults if f.active(t_s) and f.kind != "push")
