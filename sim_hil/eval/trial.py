"""One evaluation trial: the simulator in THIS process (lockstep) and the C++ runtime as a child, over LCM
on a URL of their own, so two trials can run side by side in one network namespace.

The sim runs in-process so the trial can read what only physics knows, every tick (motor torques, joint
accelerations, contact forces, foot slip), without adding fields to sim_status_t; the runtime still sees
exactly what it sees in `make demo`: T1_IMU / T1_JOINT_STATE over LCM, and in composite mode T1_SIM_STATUS,
published every tick (--status-rate 500). Trial time 0 is sim start; the runtime's autostart needs the
PREPARE ramp before POLICY (2 s from a fallen start; STANDING_PREPARE_S from a standing one, already in
the default pose), so every metric starts at the first tick the runtime commands in POLICY.
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from t1 import joint_command_t, joystick_t

from common.events import (
    FALLEN_TRUNK_HEIGHT_M,
    GetupEvents,
    getup_events,
    heading_from_quat,
    kneel_gate_mask,
    kneel_hold_s,
    lying_side,
    through_kneel_gate,
    up_z_from_quat,
)
from messages import contract
from messages.auth import RunKey
from sim_hil import config
from sim_hil.eval.metrics import TickLog, effort_metrics, ran_to_stabilise, slip_events
from sim_hil.launch import start_runtime, stop, wait_until_listening

JOYSTICK_EVERY_TICKS = 10       # 50 Hz joystick, as a gamepad; the runtime zeroes it only after 250 ms
PLOT_EVERY_TICKS = 10           # plotted series at 50 Hz
EVAL_PORT_OFFSET = 101          # trial LCM ports: contract port + this + worker index
# The operator of a course (walls, puddles) keeps the robot pointed down it, as a person with a gamepad
# would: a policy rises from a fall facing anywhere and tracks a yaw RATE, not a heading, so a constant
# stick measures where the getup left it facing, not whether it crosses the course. Proportional on the
# heading error, within the joystick's yaw range, and only while upright (a lying trunk has no heading).
STEER_GAIN_PER_S = 1.0          # yaw-rate command per rad of heading error [rad/s / rad]
STEER_MAX_RPS = 0.5             # |yaw-rate command| cap [rad/s]
STEER_MIN_UP_Z = 0.8            # steer only while the trunk's up axis is this close to vertical (≈ 37°)


@dataclass(frozen=True)
class Controller:
    """What drives the robot: one artifact (the student) or a composite pair (baseline getup + joystick)."""
    label: str
    policy: Path                  # single policy, or the composite's getup member
    upright: Path | None = None   # composite: the joystick/upright member

    def runtime_args(self) -> list[str]:
        return ["--policy-upright", str(self.upright)] if self.upright else []


@dataclass(frozen=True)
class TrialSpec:
    scenario: str                 # sim scenario (flat | walls | puddles | pushes)
    seed: int
    spawn: str                    # standing | kneeling | fallen:SEED
    seconds: float                # sim seconds
    command_vx_mps: float = 0.0   # constant forward command [m/s]
    command_yaw_rps: float = 0.0  # constant yaw-rate command [rad/s], counter-clockwise positive
    command_start_s: float = 0.0  # sim time [s] before which the command is zero
    command_stop_s: float | None = None   # sim time [s] from which the command is zero (None: never)
    steer_heading_rad: float | None = None  # operator steering to this heading (operator_yaw_rate); None:
                                            # the constant command_yaw_rps
    clock: str = "lockstep"       # lockstep (the runtime answers every state) | realtime (both on the wall clock)
    faults: str = ""              # sim --faults (pushes: push:x=±J@t)
    record: str | None = None     # mp4 path
    log: str | None = None        # .lcmlog path (sim_hil/lcmlog): every LCM message of the trial
    tag: str = ""                 # what the scenario wants to remember (e.g. "forward", "backward")
    prepare_s: float = 2.0        # the runtime's PREPARE ramp (t1-runtime --prepare-s) before POLICY


@dataclass
class TrialResult:
    spec: TrialSpec
    controller: str
    policy_start_s: float                   # nan: the runtime never reached POLICY
    events: GetupEvents | None              # over the POLICY part of the trial
    effort: dict[str, float]                # Table 4.3 metrics over the getup window
    slips: int
    ran_to_stabilise: bool
    final_x_m: float
    finish_time_s: float                    # walls: first time past the finish line (nan: DNF)
    drift_m: float = float("nan")           # horizontal distance from POLICY start to the end [m]
    yaw_turned_rad: float = float("nan")    # heading change from POLICY start to the end, unwrapped [rad]
    after_stop_m: float = float("nan")      # horizontal distance from the command's stop to the end [m]
    fall_x_m: list[float] = field(default_factory=list)   # base x at each fall / fallen start [m]
    runtime_faults: str = ""                # the runtime's latched fault text, if any
    segment_attempts: list[int] = field(default_factory=list)   # walls: getup attempts per wall segment
    segment_falls: list[int] = field(default_factory=list)
    plot: dict[str, list[float]] = field(default_factory=dict)
    through_kneel_gate: bool | None = None  # met the kneel gate before its first stand-up (None: never stood up)
    lying: str = ""                         # how it lay at POLICY start: face_down | on_back | side ("": never)
    kneel_time_s: float = float("nan")      # first time §4.8's gate held in the kneeling posture, from POLICY start
    kneel_hold_s: float = 0.0               # its longest hold in the POLICY part [s] (0: never met)


def trial_log_name(spec: TrialSpec, label: str) -> str:
    """e.g. student_pushes_forward_seed3.lcmlog: the controller, the scenario, what it tests and the seed."""
    parts = [label, spec.scenario, spec.tag, f"seed{spec.seed}"]
    return "_".join(p for p in parts if p) + ".lcmlog"


def trial_lcm_url(worker: int, base: str | None = None) -> str:
    """The contract URL on its own port for worker `worker` (ttl stays 0)."""
    return contract.lcm_url_on_port(EVAL_PORT_OFFSET + worker, base)


def run_trial(spec: TrialSpec, controller: Controller, lcm_url: str, finish_x_m: float | None = None,
              segment_edges_x: list[float] | None = None) -> TrialResult:
    from sim_hil.sim import SimConfig, Simulator  # heavy (MuJoCo, CAN); only where a trial runs
    lockstep = spec.clock == "lockstep"
    run_key = RunKey()                               # the trial's keys: the sim signs state with its robot key
    sim = Simulator(SimConfig(scenario=spec.scenario, spawn=spec.spawn, clock=spec.clock, seed=spec.seed,
                              faults=spec.faults, lcm_url=lcm_url, record=spec.record,
                              status_rate_hz=1.0 / config.LOOP_PERIOD_S, robot_key=str(run_key.robot_key_path)))
    clock_args = ("--clock", "lockstep") if lockstep else ()     # realtime: the runtime's own clock
    runtime_args = [*clock_args, "--autostart", "--prepare-s", f"{spec.prepare_s:g}", *controller.runtime_args()]
    capture = _start_log(spec, controller, runtime_args, lcm_url) if spec.log else None
    runtime = start_runtime(controller.policy, *runtime_args, "--lcm-url", lcm_url, run_key=run_key)
    signer = runtime.run_key.signer()            # the trial's operator: a fresh key of this run
    wait_until_listening(runtime)
    n = int(round(spec.seconds / config.LOOP_PERIOD_S))
    log = TickLog(sim.model, n)
    stick = joystick_t()
    wall_start = time.perf_counter()
    try:
        for k in range(n):
            # realtime: tick k starts at wall start + k·dt, the wait spent handling LCM (as Simulator.run)
            while not lockstep and (remaining := wall_start + k * config.LOOP_PERIOD_S - time.perf_counter()) > 0:
                sim.link.poll(remaining)
            if k % JOYSTICK_EVERY_TICKS == 0:
                commanding = sim.data.time >= spec.command_start_s and (
                    spec.command_stop_s is None or sim.data.time < spec.command_stop_s)
                stick.vx, stick.yaw_rate = ((float(spec.command_vx_mps), _yaw_command(spec, sim.data)) if commanding
                                            else (0.0, 0.0))
                stick.utime, stick.seq = sim.now_us, k   # lockstep: ages are in sim time
                sim.link.lc.publish(contract.CH_JOYSTICK, signer.sign(contract.CH_JOYSTICK, stick))
            sim.tick()
            latest = sim.link.latest
            log.record(k, sim.data, latest.mode if latest is not None else -1)
            if runtime.poll() is not None:
                raise RuntimeError(f"t1-runtime exited {runtime.returncode} at sim t={sim.data.time:.3f} s: "
                                   f"{runtime.communicate()[1][-2000:]}")
    finally:
        sim.close()                                 # renders the video when recording
        code, err = stop(runtime)
        if capture is not None:
            capture.stop()
    if sim.lockstep_timeouts:
        raise RuntimeError(f"{sim.lockstep_timeouts} lockstep timeouts: the runtime did not answer every state")
    return summarise(spec, controller.label, log, finish_x_m, _last_fault(err), segment_edges_x)


def operator_yaw_rate(target_heading_rad: float, heading_rad: float, up_z: float) -> float:
    """The course operator's yaw-rate command [rad/s]: P on the wrapped heading error, capped; 0 while the
    robot is not upright."""
    if up_z < STEER_MIN_UP_Z:
        return 0.0
    error = math.remainder(target_heading_rad - heading_rad, math.tau)   # wrapped to [−π, π]
    return float(np.clip(STEER_GAIN_PER_S * error, -STEER_MAX_RPS, STEER_MAX_RPS))


def _yaw_command(spec: TrialSpec, data) -> float:
    if spec.steer_heading_rad is None:
        return float(spec.command_yaw_rps)
    quat = data.qpos[3:7]
    return operator_yaw_rate(spec.steer_heading_rad, heading_from_quat(quat), float(up_z_from_quat(quat)))


def _start_log(spec: TrialSpec, controller: Controller, runtime_args: list[str], lcm_url: str):
    from common import keyframe_chain
    from common.artifact import read_artifact
    from sim_hil.lcmlog.capture import LogCapture, RunInfo
    info = RunInfo(run_name=Path(spec.log).stem, producer=f"eval:{spec.scenario}", clock=spec.clock,
                   policy_path=str(controller.policy),
                   policy_hash="+".join(read_artifact(p)[3]["content_hash"]
                                        for p in keyframe_chain.artifact_files(controller.policy)),
                   runtime_args=runtime_args,
                   sim_args=["--scenario", spec.scenario, "--spawn", spec.spawn, "--seed", str(spec.seed),
                             "--clock", spec.clock, "--faults", spec.faults])
    return LogCapture(spec.log, lcm_url, info)


def _last_fault(runtime_stderr: str) -> str:
    m = re.search(r"last fault: (.*)$", runtime_stderr.strip().splitlines()[-1] if runtime_stderr.strip() else "")
    return "" if not m or m.group(1) == "none" else m.group(1)


def summarise(spec: TrialSpec, label: str, log: TickLog, finish_x_m: float | None,
              runtime_faults: str = "", segment_edges_x: list[float] | None = None) -> TrialResult:
    """Events and metrics of one logged trial (split out so scripted logs can be checked without a sim)."""
    in_policy = np.flatnonzero(log.mode == joint_command_t.MODE_POLICY)
    start = int(in_policy[0]) if in_policy.size else None
    events, effort, fall_x, gate, kneel = None, {}, [], None, {}
    if start is not None:
        sl = slice(start, None)
        events = getup_events(log.t[sl], log.trunk[sl], log.up_z[sl])
        gate = through_kneel_gate(log.t[sl], log.trunk[sl], log.up_z[sl], events)
        kneel = _kneel(log, start)
        starts_down = bool(log.trunk[start] < FALLEN_TRUNK_HEIGHT_M)
        fall_ticks = [int(np.searchsorted(log.t, ft)) for ft in events.fall_times_s]
        fall_x = [float(log.base_x[i]) for i in ([start] if starts_down else []) + fall_ticks]
        # Table 4.3 window: the first time down, from going down (or POLICY start) to the stand-up; the
        # rest of the POLICY part when it never stands up; the whole POLICY part when it never went down.
        begin, end = start, log.n
        if starts_down or events.falls:
            first_down_t = log.t[start] if starts_down else events.fall_times_s[0]
            begin = int(np.searchsorted(log.t, first_down_t))
            if not np.isnan(events.time_to_stand_s):
                end = int(np.searchsorted(log.t, first_down_t + events.time_to_stand_s))
        effort = effort_metrics(log, begin, max(end, begin + 1))
    finish = np.nan
    if finish_x_m is not None:
        past = np.flatnonzero(log.base_x >= finish_x_m)
        finish = float(log.t[past[0]]) if past.size else np.nan
    seg_attempts, seg_falls = [], []
    if segment_edges_x and start is not None:
        # each segment's ticks (POLICY part) in order; a down phase stays where the robot lies
        x = log.base_x[start:]
        for lo, hi in zip(segment_edges_x, segment_edges_x[1:]):
            idx = start + np.flatnonzero((x >= lo) & (x < hi))
            seg = getup_events(log.t[idx], log.trunk[idx], log.up_z[idx]) if idx.size else None
            seg_attempts.append(seg.attempts if seg else 0)
            seg_falls.append(seg.falls + int(log.trunk[idx[0]] < FALLEN_TRUNK_HEIGHT_M and idx[0] > start)
                             if seg else 0)
    sl = slice(start if start is not None else log.n, None)
    drift, turned = np.nan, np.nan
    if start is not None:
        drift = float(np.hypot(log.base_x[-1] - log.base_x[start], log.base_y[-1] - log.base_y[start]))
        turned = float(np.unwrap(log.yaw[start:])[-1] - log.yaw[start])
    after_stop = np.nan
    if spec.command_stop_s is not None and log.n:
        stop = min(int(np.searchsorted(log.t, spec.command_stop_s)), log.n - 1)
        after_stop = float(np.hypot(log.base_x[-1] - log.base_x[stop], log.base_y[-1] - log.base_y[stop]))
    every = slice(None, None, PLOT_EVERY_TICKS)
    return TrialResult(
        spec=spec, controller=label,
        policy_start_s=float(log.t[start]) if start is not None else np.nan,
        events=events, effort=effort, slips=slip_events(log, sl), ran_to_stabilise=ran_to_stabilise(log, sl),
        final_x_m=float(log.base_x[-1]) if log.n else np.nan, finish_time_s=finish, fall_x_m=fall_x,
        drift_m=drift, yaw_turned_rad=turned, after_stop_m=after_stop,
        runtime_faults=runtime_faults, segment_attempts=seg_attempts, segment_falls=seg_falls,
        through_kneel_gate=gate, **kneel,
        plot={"t": log.t[every].tolist(), "trunk": log.trunk[every].tolist(), "waist": log.waist[every].tolist(),
              "vx": log.fwd_vel[every].tolist()})


def _kneel(log: TickLog, start: int) -> dict:
    """Stage 1's figures over the POLICY part: how it lay, when §4.8's gate first held in the kneeling posture
    and its longest hold (common/events.py)."""
    sl = slice(start, None)
    met = np.flatnonzero(kneel_gate_mask(log.trunk[sl], log.up_z[sl]) & (log.kneeling[sl] > 0))
    return {"lying": lying_side(float(log.forward_z[start])),
            "kneel_time_s": float(log.t[start + met[0]] - log.t[start]) if met.size else float("nan"),
            "kneel_hold_s": kneel_hold_s(log.trunk[sl], log.up_z[sl], log.kneeling[sl], config.LOOP_PERIOD_S)}


# ---- pool workers (module level: a spawned worker imports them by name) --------------------------------
_worker_url = ""


def init_worker(slots) -> None:
    """Pool initializer: take a free worker slot -> this worker's own LCM URL for all its trials."""
    global _worker_url
    _worker_url = trial_lcm_url(slots.get())


def run_job(job) -> TrialResult:
    spec, controller, finish_x_m, segment_edges_x = job
    return run_trial(spec, controller, _worker_url, finish_x_m, segment_edges_x)
