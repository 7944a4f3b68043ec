"""Decoded project messages → Rerun entities, a batch at a time: a whole log in one batch (sim_hil.lcmlog
rerun) or what the live bridge gathered since its last flush; both write the same entities.

Every row lies on `log_time`, the time the message was received (the logger's wall clock in a log, the
bridge's in a live run); a log also gets `sim_time` (sim_hil.lcmlog.plot.sim_clock). Continuous signals get
one row per message of their channel; the runtime's mode, faults and refusals, commands and the
simulator's injected faults become text events in `runtime/events` when they change."""
from __future__ import annotations

import re
from collections import Counter
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np
import rerun as rr
from t1 import controller_status_t

from messages import contract
from sim_hil.rerun_view.columns import Columns
from sim_hil.rerun_view.robot import POSE_FROM_IMU, POSE_FROM_SIM, RobotGeoms

TIMELINE = "log_time"
SIM_TIMELINE = "sim_time"
EVENTS = "runtime/events"
# multi-series entities: path -> (channel, fields or (field, index) pairs, series names)
SERIES = {
    "command/joystick": (contract.CH_JOYSTICK, ("vx", "vy", "yaw_rate"),
                         ("vx [m/s]", "vy [m/s]", "yaw rate [rad/s]")),
    "trunk/velocity": (contract.CH_SIM_STATUS, (("base_lin_vel", 0), ("base_lin_vel", 1), ("base_lin_vel", 2),
                                                "forward_velocity"),
                       ("world vx [m/s]", "world vy [m/s]", "world vz [m/s]", "forward [m/s]")),
    "trunk/height": (contract.CH_SIM_STATUS, ("trunk_height", "waist_height"), ("trunk [m]", "waist [m]")),
    "runtime/timing/lateness_us": (contract.CH_CONTROLLER_STATUS, ("lateness_us_last", "lateness_us_p99"),
                                   ("wake-up lateness [us]", "lateness p99 [us]")),
    "runtime/timing/tick_us": (contract.CH_CONTROLLER_STATUS, ("compute_us_last", "compute_us_p99"),
                               ("tick compute [us]", "tick compute p99 [us]")),
    "runtime/mode": (contract.CH_CONTROLLER_STATUS, ("mode",), ("mode (joint_command_t.MODE_*)",)),
}
# per joint: entity leaf -> (channel, field)
JOINT_SIGNALS = {"q": (contract.CH_JOINT_STATE, "q"), "q_des": (contract.CH_JOINT_CMD, "q_des"),
                 "tau_est": (contract.CH_JOINT_STATE, "tau_est")}
# what the recording is made of (a log is decoded on these alone)
CHANNELS_SHOWN = frozenset({contract.CH_RUN_INFO, contract.CH_RUNTIME_CMD, contract.CH_CONTROLLER_STATUS,
                            contract.CH_SIM_STATUS, contract.CH_IMU, contract.CH_JOINT_STATE, contract.CH_JOINT_CMD,
                            contract.CH_JOYSTICK})
# channels whose messages become text events (low rate: read message by message)
EVENT_CHANNELS = (contract.CH_RUN_INFO, contract.CH_RUNTIME_CMD, contract.CH_CONTROLLER_STATUS, contract.CH_SIM_STATUS)
REFUSAL_FIELDS = tuple(f for f in controller_status_t.__slots__ if "refused_" in f)
IDENTITY_QUAT = (1.0, 0.0, 0.0, 0.0)
# the supervisor's fault and warning bits are named in one place, the runtime's header
SAFETY_HEADER = Path(__file__).resolve().parents[2] / "runtime" / "include" / "t1rt" / "safety.hpp"


@lru_cache(maxsize=1)
def _bit_names() -> dict[int, str]:
    try:
        text = SAFETY_HEADER.read_text()
    except OSError:
        return {}
    return {int(bit): name for name, bit in re.findall(r"int32_t k(\w+) = 1 << (\d+);", text)}


def fault_text(bits: int) -> str:
    """`bits` as the header's names, e.g. "TargetClamped, RateLimited" (unnamed bits as numbers)."""
    names = _bit_names()
    return ", ".join(names.get(b, f"bit {b}") for b in range(32) if bits >> b & 1)


def joint_entity(name: str, leaf: str) -> str:
    return f"joints/{name}/{leaf}"


def stamps_of(entries) -> np.ndarray:
    """Receive stamps [us] of a channel's entries: [(stamp, message), ...] or Columns (columns.py)."""
    return entries.stamps if isinstance(entries, Columns) else np.array([s for s, _ in entries], np.int64)


def values_of(entries, spec) -> np.ndarray:
    """One field per row (float); spec: a field name or (field, index) for one element of an array field."""
    name, index = spec if isinstance(spec, tuple) else (spec, None)
    column = entries[name] if isinstance(entries, Columns) else np.array([getattr(m, name) for _, m in entries], float)
    return column if index is None else column[:, index]


def _held(prev, stamps: np.ndarray, values: np.ndarray, at: np.ndarray, default) -> np.ndarray:
    """The latest value at or before each of `at` (prev: (stamp, value) carried from earlier batches)."""
    if prev is not None:
        stamps = np.concatenate([[prev[0]], stamps])
        values = np.concatenate([[prev[1]], values]) if len(values) else np.asarray([prev[1]])
    idx = np.searchsorted(stamps, at, side="right") - 1
    out = np.tile(np.asarray(default, float), (len(at), 1))
    ok = idx >= 0
    if ok.any():
        out[ok] = np.asarray(values, float)[idx[ok]]
    return out


class RunRecorder:
    """Writes batches {channel: [(receive stamp [us], message), ...] in time order} to `rec`."""

    def __init__(self, rec: rr.RecordingStream, robot: RobotGeoms | None = None,
                 sim_clock: Callable | None = None):
        self.rec, self.robot, self.sim_clock = rec, robot, sim_clock
        self._imu = self._base = self._status = self._sim = self._motor = None
        self._pose_note = None
        self.rows = Counter()      # entity -> rows written (the tests compare them with the log's counts)
        for path, (_, _, names) in SERIES.items():
            rec.log(path, rr.SeriesLines(names=list(names)), static=True)

    def times(self, stamps_us) -> list:
        stamps = np.asarray(stamps_us, np.int64)
        cols = [rr.TimeColumn(TIMELINE, timestamp=stamps.astype("datetime64[us]"))]
        if self.sim_clock is not None:
            cols.append(rr.TimeColumn(SIM_TIMELINE, duration=np.asarray(self.sim_clock(stamps), float)))
        return cols

    def _send(self, path: str, stamps, values: np.ndarray) -> None:
        self.rec.send_columns(path, indexes=self.times(stamps), columns=rr.Scalars.columns(scalars=values))
        self.rows[path] += len(stamps)

    def write(self, batch: dict) -> None:
        """batch: channel -> [(stamp, message), ...] in time order, or Columns for the busy channels."""
        events: list[tuple[int, str, str]] = []
        for channel in EVENT_CHANNELS:
            for stamp, msg in batch.get(channel, ()):
                events += self._events(channel, stamp, msg)
        for path, (channel, fields, _) in SERIES.items():
            entries = batch.get(channel, ())
            if len(entries):
                self._send(path, stamps_of(entries), np.column_stack([values_of(entries, f) for f in fields]))
        for leaf, (channel, field) in JOINT_SIGNALS.items():
            entries = batch.get(channel, ())
            if len(entries):
                stamps, values = stamps_of(entries), values_of(entries, field)
                for j, name in enumerate(contract.JOINT_NAMES):
                    self._send(joint_entity(name, leaf), stamps, values[:, j])
        events += self._motor_events(batch.get(contract.CH_JOINT_STATE, ()))
        self._pose(batch)
        if events:
            events.sort(key=lambda e: e[0])
            self.rec.send_columns(EVENTS, indexes=self.times([e[0] for e in events]),
                                  columns=rr.TextLog.columns(text=[e[1] for e in events], level=[e[2] for e in events]))
            self.rows[EVENTS] += len(events)

    def _pose(self, batch: dict[str, list]) -> None:
        imu, sim = batch.get(contract.CH_IMU, []), batch.get(contract.CH_SIM_STATUS, [])
        states = batch.get(contract.CH_JOINT_STATE, [])
        from_sim = len(sim) > 0 or self._base is not None
        if self.robot is not None and (self._pose_note is None or (from_sim and self._pose_note != POSE_FROM_SIM)):
            self._pose_note = POSE_FROM_SIM if from_sim else POSE_FROM_IMU
            self.robot.log_shapes(self.rec, self._pose_note)
        imu_quat = values_of(imu, "quat") if len(imu) else np.zeros((0, 4))
        base_pos = values_of(sim, "base_pos") if len(sim) else np.zeros((0, 3))
        if self.robot is not None and len(states):
            at = stamps_of(states)
            quat = _held(self._imu, stamps_of(imu), imu_quat, at, IDENTITY_QUAT)
            standing = (0.0, 0.0, contract.NOMINAL_STANDING_TRUNK_HEIGHT_M)
            pos = _held(self._base, stamps_of(sim), base_pos, at, standing)
            self.robot.send_poses(self.rec, self.times(at), pos, quat, values_of(states, "q"))
            self.rows["robot/geoms"] += len(states)
        if len(imu):
            self._imu = (stamps_of(imu)[-1], imu_quat[-1])
        if len(sim):
            self._base = (stamps_of(sim)[-1], base_pos[-1])

    def _motor_events(self, states) -> list[tuple[int, str, str]]:
        """An event where any motor's status bits change (the first row against all clear)."""
        if not len(states):
            return []
        status = values_of(states, "motor_status").astype(np.int64)
        before = np.vstack([self._motor if self._motor is not None else np.zeros(contract.NUM_JOINTS, np.int64),
                            status[:-1]])
        stamps, out = stamps_of(states), []
        for i in np.flatnonzero((status != before).any(axis=1)):
            bad = [f"{contract.JOINT_NAMES[j]} {bits:#x}" for j, bits in enumerate(status[i]) if bits]
            out.append((int(stamps[i]), f"motor status: {', '.join(bad) or 'all clear'}", "WARN" if bad else "INFO"))
        self._motor = status[-1]
        return out

    def _events(self, channel: str, stamp: int, msg) -> list[tuple[int, str, str]]:
        if channel == contract.CH_RUN_INFO:
            return [(stamp, f"run {msg.run_name!r} by {msg.producer} ({msg.clock}); policy "
                            f"{msg.policy_path or '-'}; runtime args: {msg.runtime_args or '-'}", "INFO")]
        if channel == contract.CH_RUNTIME_CMD:
            return [(stamp, f"command {msg.verb} {msg.argument} (sender {msg.sender_id})".rstrip(), "INFO")]
        if channel == contract.CH_SIM_STATUS:
            prev, self._sim = self._sim, msg
            out = []
            if msg.active_faults != (prev.active_faults if prev else ""):
                out.append((stamp, f"sim faults: {msg.active_faults or 'none'}",
                            "WARN" if msg.active_faults else "INFO"))
            if msg.fallen != (prev.fallen if prev else False):
                out.append((stamp, "fallen" if msg.fallen else "upright again", "WARN" if msg.fallen else "INFO"))
            return out
        prev, self._status = self._status, msg
        out = []
        if prev is None or msg.mode_name != prev.mode_name:
            out.append((stamp, f"mode {prev.mode_name if prev else 'start'} → {msg.mode_name}", "INFO"))
        if (msg.fault_bits, msg.last_fault) != ((prev.fault_bits, prev.last_fault) if prev else (0, "")):
            latched = msg.fault_bits & controller_status_t.LATCHED_FAULT_MASK
            text = (f"supervisor {'fault' if latched else 'warning'}: {fault_text(msg.fault_bits)}"
                    f"{'; ' + msg.last_fault if msg.last_fault else ''}" if msg.fault_bits else "faults cleared")
            out.append((stamp, text, "ERROR" if latched else "WARN" if msg.fault_bits else "INFO"))
        for field in REFUSAL_FIELDS:
            grew = getattr(msg, field) - (getattr(prev, field) if prev else 0)
            if grew > 0:
                out.append((stamp, f"{field.replace('_', ' ')}: +{grew} ({getattr(msg, field)} in all)", "WARN"))
        if msg.info and msg.info != (prev.info if prev else ""):
            out.append((stamp, f"runtime: {msg.info}", "INFO"))
        return out
