"""The simulated T1: MuJoCo physics behind the emulated motor bus, driven over LCM (or, with --dds, over
the real T1's own DDS topics: sim_hil/dds_bridge.py).

One control tick k (2 ms of sim time):
  1. publish state k: T1_IMU and T1_JOINT_STATE (decoded from the motors' reply frames), stamped with
     sim time;
  2. get the command: lockstep waits for the one answering state k (state_seq = k; a timeout is counted
     and the motors keep their last command, so their watchdog decides); realtime takes the newest;
  3. bus cycle: 23 command frames onto the 4 buses → firmware_like motors;
  4. physics substeps: each motor's firmware step gives its torque from its (possibly frozen) encoder,
     MuJoCo integrates; scheduled pushes are applied as torso impulses;
  5. reply frames back to the host: that is state k+1.
Realtime mode paces ticks against the wall clock; lockstep runs as fast as the client answers.
"""
from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass

import mujoco
import numpy as np
from t1 import sim_status_t

from common import model as t1model
from common import scenarios
from common.events import FALLEN_TRUNK_HEIGHT_M
from messages.auth import read_key_file
from sim_hil import config, motor_bus
from sim_hil.faults import FaultSchedule, parse_faults
from sim_hil.imu import Imu
from sim_hil.lcm_bridge import LcmBridge
from sim_hil.motor_bus import open_motor_bus


@dataclass
class SimConfig:
    scenario: str = "flat"
    spawn: str = "standing"          # standing | kneeling | fallen:SEED
    clock: str = "lockstep"          # lockstep | realtime
    seed: int = 0
    duration_s: float | None = None  # None = run until interrupted
    physics_dt_s: float = config.DEFAULT_PHYSICS_DT_S
    faults: str = ""
    lcm_url: str = ""
    can_interface: str = "direct"        # direct | virtual | udp_multicast (motor_bus.py)
    can_log: str | None = None
    record: str | None = None
    lockstep_timeout_s: float = config.LOCKSTEP_TIMEOUT_S
    status_rate_hz: float = config.STATUS_RATE_HZ
    dds: bool = False                # serve rt/low_state + rt/joint_ctrl (DDS) instead of the LCM state/command
    viewer: bool = False             # MuJoCo's interactive viewer on the run (sim_hil/viewer.py)
    python_tick: bool = False        # every tick in Python: the reference the C++ lockstep tick is tested against
    rt: bool = False                 # realtime clock under SCHED_FIFO (the runtime's --rt counterpart)
    robot_key: str | None = None     # sign the LCM state with this robot key file (messages/auth.py); None: unsigned


def parse_spawn(spawn: str) -> tuple[str, int]:
    kind, _, seed = spawn.partition(":")
    if kind not in ("standing", "kneeling", "fallen"):
        raise ValueError(f"--spawn '{spawn}': expected standing | kneeling | fallen:SEED")
    if kind == "fallen":
        if not seed.isdigit():
            raise ValueError(f"--spawn '{spawn}': fallen needs a non-negative integer seed, e.g. fallen:3")
        return kind, int(seed)
    if seed:
        raise ValueError(f"--spawn '{spawn}': only fallen takes a seed")
    return kind, 0


class Simulator:
    def __init__(self, cfg: SimConfig):
        if cfg.clock not in ("lockstep", "realtime"):
            raise ValueError(f"--clock '{cfg.clock}': expected lockstep | realtime")
        if cfg.rt and cfg.clock != "realtime":
            raise ValueError("--rt needs --clock realtime (lockstep runs as fast as its client answers)")
        if cfg.duration_s is not None and not (math.isfinite(cfg.duration_s) and cfg.duration_s > 0):
            raise ValueError(f"--duration {cfg.duration_s}: must be a finite number of seconds > 0 "
                             "(leave it out to run until interrupted)")
        if not (math.isfinite(cfg.lockstep_timeout_s) and cfg.lockstep_timeout_s > 0):
            raise ValueError(f"--lockstep-timeout {cfg.lockstep_timeout_s}: must be a finite number of seconds > 0")
        # Checked before dividing: 0, negative, nan and inf are refused with the option named.
        valid_dt = math.isfinite(cfg.physics_dt_s) and cfg.physics_dt_s > 0
        substeps = config.LOOP_PERIOD_S / cfg.physics_dt_s if valid_dt else float("nan")
        if not valid_dt or abs(substeps - round(substeps)) > 1e-9:
            raise ValueError(f"--physics-dt {cfg.physics_dt_s}: must divide the {config.LOOP_PERIOD_S} s "
                             "control period (0.002, 0.001, 0.0005, ...)")
        spawn_kind, spawn_seed = parse_spawn(cfg.spawn)
        faults = parse_faults(cfg.faults)      # raises FaultSpecError with the bad part named
        self.cfg = cfg
        self.substeps = int(round(substeps))
        self.model, self.scenario = scenarios.build(cfg.scenario, cfg.seed)
        self.model.opt.timestep = cfg.physics_dt_s
        self.data = mujoco.MjData(self.model)
        qpos, qvel = t1model.spawn_state(self.model, spawn_kind, spawn_seed)
        self.data.qpos[:], self.data.qvel[:] = qpos, qvel
        self.data.time = 0.0
        mujoco.mj_forward(self.model, self.data)

        pushes = [f"push:x={p[0]},y={p[1]},z={p[2]}@{t}" for t, p in self.scenario.pushes]
        self.faults = FaultSchedule(faults + parse_faults(";".join(pushes)))
        self.rng = np.random.default_rng(cfg.seed)
        self.imu = Imu(self.model, self.rng)
        self.bus = open_motor_bus(cfg.can_interface, cfg.can_log, self.rng)
        if cfg.rt:
            self._enter_fifo()       # before the link's threads start: they inherit the policy
        # The robot link: LCM, or the real T1's DDS topics (a DdsBridge has the LcmBridge's interface).
        if cfg.dds:
            from sim_hil.dds_bridge import DdsBridge
            self.link = DdsBridge(cfg.lcm_url)
        else:
            self.link = LcmBridge(cfg.lcm_url)
            if cfg.robot_key:
                self.link.sign_state(read_key_file(cfg.robot_key)[0])
        self.trunk_id = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, "Trunk")
        self.seq = 0
        self.lockstep_timeouts = 0
        self._frozen_q: dict[int, float] = {}
        if not 0 < cfg.status_rate_hz <= 1.0 / config.LOOP_PERIOD_S:
            raise ValueError(f"--status-rate {cfg.status_rate_hz}: must be in (0, {1 / config.LOOP_PERIOD_S:g}] Hz")
        self._status_every = max(1, int(round(1.0 / (cfg.status_rate_hz * config.LOOP_PERIOD_S))))
        self._rtf = 0.0
        self._rtf_mark = (time.perf_counter(), 0.0)
        self.recorder = None
        if cfg.record:
            from sim_hil.recorder import Recorder
            from sim_hil.runtime_view import RuntimeView
            self.recorder = Recorder(self.model, cfg.record, caption=RuntimeView(self.link).caption)
        self.viewer = None
        if cfg.viewer:
            from sim_hil.viewer import LiveViewer
            self.viewer = LiveViewer.open(self)      # None (said why) without a display: run headless
        # The lockstep tick in one C++ call where it needs nothing from Python (tick_core.py); the LCM link and
        # the C buses are what it steps, so DDS, the python-can buses and --python-tick keep the Python tick.
        self._core_tick = None
        self._commanded = False       # a valid command has arrived (lockstep waits longer for the first)
        if (cfg.clock == "lockstep" and not cfg.python_tick and isinstance(self.link, LcmBridge)
                and isinstance(self.bus, motor_bus.DirectMotorBus)):
            from sim_hil.tick_core import LockstepTick
            self._core_tick = LockstepTick(self.link.core, self.model, self.data, self.bus, self.substeps,
                                           self.imu.addresses)
        # Power-on: motors answer once so the host has a state to publish at k = 0.
        self.bus.exchange_replies(*self._encoders(), self.data.qfrc_actuator[6:].copy(), 0)

    # ---- helpers -------------------------------------------------------------------------------------
    @property
    def now_us(self) -> int:
        return int(round(self.data.time * 1e6))

    def _encoders(self) -> tuple[np.ndarray, np.ndarray]:
        """What the motor encoders read: true joint state, except frozen encoders stuck at their value."""
        q = self.data.qpos[7:].copy()
        dq = self.data.qvel[6:].copy()
        frozen = self.faults.frozen_joints(self.data.time)
        for i in list(self._frozen_q):
            if i not in frozen:
                del self._frozen_q[i]
        for i in frozen:
            q[i] = self._frozen_q.setdefault(i, q[i])
            dq[i] = 0.0
        return q, dq

    def _enter_fifo(self) -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(config.RT_FIFO_PRIORITY))
        except PermissionError as exc:
            print(f"sim_hil: --rt: SCHED_FIFO refused ({exc}); running at normal priority", file=sys.stderr)

    def _wait_until(self, deadline: float) -> None:
        """Realtime: handle LCM until the tick's deadline, the last REALTIME_SPIN_S in a busy loop so the
        state goes out on time rather than when a sleep happens to wake."""
        while (remaining := deadline - time.perf_counter()) > config.REALTIME_SPIN_S:
            self.link.poll(remaining - config.REALTIME_SPIN_S)
        while time.perf_counter() < deadline:
            pass

    def _publish_state(self) -> None:
        t = self.data.time
        quat, gyro, accel = self.imu.read(self.data, self.faults.imu_noise(t), self.faults.imu_bias(t))
        b = self.bus
        self.link.publish_state(self.now_us, self.seq, quat, gyro, accel, b.q, b.dq, b.tau, b.status)

    def _trunk_force(self) -> np.ndarray | None:
        """The outside force on the torso now [N]: the pushes due (an impulse J [N·s] is a constant force J/dt
        over one physics step) and the active loads. The caller adds it to xfrc_applied around that step
        only, so a force already there (the viewer's mouse perturbation) is kept, not overwritten."""
        due = self.faults.due_pushes(self.data.time)
        load = self.faults.trunk_load(self.data.time)
        if not due and load is None:
            return None
        force = np.sum(due, axis=0) / self.model.opt.timestep if due else np.zeros(3)
        return force + (load if load is not None else 0.0)

    def status_message(self) -> sim_status_t:
        s = sim_status_t()
        s.utime, s.step = self.now_us, self.seq
        s.real_time_factor = float(self._rtf)
        s.scenario, s.clock = self.scenario.name, self.cfg.clock
        s.active_faults = self.faults.describe(self.data.time)
        s.trunk_height = float(t1model.trunk_height(self.data))
        s.waist_height = float(t1model.waist_height(self.data))
        s.fallen = s.trunk_height < FALLEN_TRUNK_HEIGHT_M
        s.base_pos = self.data.qpos[:3].tolist()
        s.base_lin_vel = self.data.qvel[:3].tolist()
        w, x, y, z = self.data.qpos[3:7]
        yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        s.forward_velocity = float(np.cos(yaw) * self.data.qvel[0] + np.sin(yaw) * self.data.qvel[1])
        s.lockstep_timeouts, s.cmds_dropped = self.lockstep_timeouts, self.link.cmds_dropped
        s.frames_late = self.bus.frames_late
        s.bus_utilisation = [float(u) for u in self.bus.utilisation()]
        return s

    # ---- the tick ------------------------------------------------------------------------------------
    def tick(self) -> None:
        t = self.data.time
        dead, drop = self.faults.dead_joints(t), self.faults.drop_rate(t)
        if self._core_tick is not None and not self._needs_python(t):
            self._frozen_q.clear()          # no encoder is frozen now
            answered = self._core_tick(self.seq, self._lockstep_wait_s(), motor_bus.mask(dead),
                                       self.bus.lost_mask(drop), self.bus.lost_mask(drop), self.faults.delay_ticks(t))
            self.lockstep_timeouts += not answered
        else:
            self._python_tick(dead, drop)
        self.seq += 1
        if self.recorder is not None:
            self.recorder.maybe_capture(self.data)
        self._maybe_publish_status()

    def advance(self, max_ticks: int) -> int:
        """Up to max_ticks lockstep ticks, as many as need nothing from Python in one C++ call (to the next
        status message or fault edge), else one tick(); how many ran. Every tick is the one tick() would be."""
        n = self._batchable_ticks(max_ticks)
        if n <= 1:
            self.tick()
            return 1
        t = self.data.time
        self._frozen_q.clear()
        answered = self._core_tick.run(self.seq, n, self._lockstep_wait_s(), motor_bus.mask(self.faults.dead_joints(t)),
                                       self.faults.delay_ticks(t))
        self.lockstep_timeouts += n - answered
        self.seq += n
        self._maybe_publish_status()
        return n

    def _batchable_ticks(self, max_ticks: int) -> int:
        """How many ticks from now run in one C++ call: none needs Python (a status message ends a batch; a
        recorder, a lost frame drawn per tick or a fault edge inside a tick keep it to one)."""
        if self._core_tick is None or self.recorder is not None or not self._commanded:
            return 1
        t = self.data.time
        if self.faults.drop_rate(t) > 0.0 or self._needs_python(t):
            return 1
        n = min(max_ticks, self._status_every - self.seq % self._status_every)
        quiet_s = self.faults.next_change_s(t) - t - config.FAULT_EDGE_MARGIN_S
        return min(n, int(quiet_s / config.LOOP_PERIOD_S)) if math.isfinite(quiet_s) else n

    def _maybe_publish_status(self) -> None:
        if self.seq % self._status_every == 0:
            wall, sim_t = time.perf_counter(), self.data.time
            self._rtf = (sim_t - self._rtf_mark[1]) / max(wall - self._rtf_mark[0], 1e-9)
            self._rtf_mark = (wall, sim_t)
            self.link.publish_status(self.status_message())

    @property
    def awaiting_first_command(self) -> bool:
        """Lockstep and no command taken yet: state 0 waits for a controller to answer it."""
        return self.cfg.clock == "lockstep" and not self._commanded

    def _lockstep_wait_s(self) -> float:
        """The client may still be starting until its first command: wait longer for that one."""
        if not self._commanded:
            self._commanded = self.link.cmds_received > 0
        return self.cfg.lockstep_timeout_s if self._commanded else config.LOCKSTEP_FIRST_COMMAND_TIMEOUT_S

    def _needs_python(self, t: float) -> bool:
        """Whether this tick needs what only the Python tick does: IMU noise or bias, a frozen encoder, a push,
        the live view's mouse."""
        return self.viewer is not None or self.faults.needs_python_tick(t, t + config.LOOP_PERIOD_S)

    def _python_tick(self, dead: set[int], drop: float) -> None:
        self._publish_state()
        if self.cfg.clock == "lockstep":
            if not self.link.wait_for_answer(self.seq, self._lockstep_wait_s(), time.perf_counter):
                self.lockstep_timeouts += 1
        else:
            self.link.poll(0.0)
        t = self.data.time
        fresh = self.link.take_frames()
        self.bus.send_commands(fresh, self.now_us, drop, self.faults.delay_ticks(t), dead)
        for _ in range(self.substeps):
            q_enc, dq_enc = self._encoders()
            tau = self.bus.motor_torques(q_enc, dq_enc, self.now_us, dead)
            self.data.ctrl[:] = tau
            if self.viewer is not None:
                self.viewer.apply_perturbation(self.data)
            force = self._trunk_force()
            if force is not None:
                self.data.xfrc_applied[self.trunk_id, :3] += force
            presses = self.faults.joint_presses(self.data.time)
            for i, press_nm in presses.items():
                self.data.qfrc_applied[6 + i] += press_nm
            mujoco.mj_step(self.model, self.data)
            if force is not None:
                self.data.xfrc_applied[self.trunk_id, :3] -= force
            for i, press_nm in presses.items():
                self.data.qfrc_applied[6 + i] -= press_nm
        q_enc, dq_enc = self._encoders()
        self.bus.exchange_replies(q_enc, dq_enc, tau, self.now_us, drop, dead)

    def run(self, on_status=None) -> None:
        """Tick until duration (or forever). Realtime: tick k starts at wall start + k·dt."""
        n_ticks = None if self.cfg.duration_s is None else int(round(self.cfg.duration_s / config.LOOP_PERIOD_S))
        start = time.perf_counter()
        try:
            while n_ticks is None or self.seq < n_ticks:
                if self.cfg.clock == "realtime":
                    self._wait_until(start + self.seq * config.LOOP_PERIOD_S)
                    self.tick()
                else:
                    self.advance(self._status_every if n_ticks is None else n_ticks - self.seq)
                if self.viewer is not None:
                    self.viewer.maybe_sync(self)
                if on_status is not None and self.seq % self._status_every == 0:
                    on_status(self)
        finally:
            self.close()

    def close(self) -> None:
        if self.viewer is not None:
            self.viewer.close()
            self.viewer = None
        if self.recorder is not None:
            self.recorder.close()
            self.recorder = None
        self.bus.close()
        self.link.close()
