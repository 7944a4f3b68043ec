"""Plays the robot for an out-of-process `t1-runtime` over LCM (inside tools/netns), the way an outside
fault client would: publishes T1_IMU / T1_JOINT_STATE / T1_JOYSTICK / T1_RUNTIME_CMD, and records the
runtime's T1_JOINT_CMD, T1_CONTROLLER_STATUS and T1_OBS. The runtime runs with a fresh key of the run
(sim_hil.launch.start_runtime); command() and joystick() sign as its operator. Used by
tests/test_runtime_lcm_faults.py and tests/test_runtime_auth.py."""
from __future__ import annotations

import time

import lcm
import numpy as np
from t1 import controller_status_t, imu_t, joint_command_t, joint_state_t, joystick_t, observation_t, runtime_cmd_t

from common.artifact import read_artifact
from messages import contract
from sim_hil.launch import start_runtime, stop

TICK_US = 2000                 # runtime loop period [us]
ANSWER_TIMEOUT_S = 5.0         # liveness bound for one answer (not a timing check)
MODE = {name: getattr(joint_command_t, f"MODE_{name}") for name in ("PASSIVE", "DAMPING", "PREPARE", "POLICY", "FAULT")}
LATCHED_FAULT_MASK = controller_status_t.LATCHED_FAULT_MASK   # fault_bits & this: latched FAULT causes


class RuntimePeer:
    """One t1-runtime child process and the fake robot talking to it."""

    def __init__(self, policy, *runtime_args: str, lockstep: bool = True, sign: bool = True):
        self.lc = lcm.LCM(contract.lcm_url())
        self.cmds: list[joint_command_t] = []
        self.statuses: list[controller_status_t] = []
        self.obs: list[observation_t] = []
        self.lc.subscribe(contract.CH_JOINT_CMD, lambda _c, d: self.cmds.append(joint_command_t.decode(d)))
        self.lc.subscribe(contract.CH_CONTROLLER_STATUS,
                          lambda _c, d: self.statuses.append(controller_status_t.decode(d)))
        self.lc.subscribe(contract.CH_OBS, lambda _c, d: self.obs.append(observation_t.decode(d)))
        self.manifest = read_artifact(policy)[3]
        self.q = np.asarray(self.manifest["default_pose"], np.float64).copy()
        self.dq = np.zeros(contract.NUM_JOINTS)
        self.motor_status = [0] * contract.NUM_JOINTS
        self.seq = 0
        self.lockstep = lockstep
        self.started = False
        clock = "lockstep" if lockstep else "realtime"
        self.proc = start_runtime(policy, "--clock", clock, *runtime_args, sign=sign)
        self.run_key = self.proc.run_key
        self.signer = self.run_key.signer() if self.run_key else None

    # ---------------------------------------------------------------- publishing
    def state_msg(self, seq: int | None = None) -> joint_state_t:
        js = joint_state_t()
        js.seq = self.seq if seq is None else seq
        js.utime = js.seq * TICK_US
        js.q, js.dq = [float(v) for v in self.q], [float(v) for v in self.dq]
        js.tau_est, js.motor_status = [0.0] * contract.NUM_JOINTS, list(self.motor_status)
        return js

    def imu_msg(self, seq: int | None = None, quat=(1.0, 0.0, 0.0, 0.0)) -> imu_t:
        imu = imu_t()
        imu.seq = self.seq if seq is None else seq
        imu.utime = imu.seq * TICK_US
        imu.quat, imu.gyro, imu.accel = list(quat), [0.0] * 3, [0.0, 0.0, 9.81]
        return imu

    def publish(self, channel: str, data: bytes) -> None:
        self.lc.publish(channel, data)

    def command_msg(self, verb: str, argument: str = "") -> runtime_cmd_t:
        c = runtime_cmd_t()
        c.utime, c.verb, c.argument = self.seq * TICK_US, verb, argument
        return c

    def joystick_msg(self, vx: float, vy: float, yaw_rate: float) -> joystick_t:
        js = joystick_t()
        js.utime, js.seq, js.vx, js.vy, js.yaw_rate = self.seq * TICK_US, self.seq, vx, vy, yaw_rate
        return js

    def signed(self, channel: str, msg) -> bytes:
        """msg's encoding, signed as the operator when the runtime has the run's key (else as lcm-gen encodes
        it: unsigned)."""
        return self.signer.sign(channel, msg) if self.signer else msg.encode()

    def command(self, verb: str, argument: str = "") -> None:
        self.publish(contract.CH_RUNTIME_CMD, self.signed(contract.CH_RUNTIME_CMD, self.command_msg(verb, argument)))

    def joystick(self, vx: float, vy: float, yaw_rate: float) -> None:
        self.publish(contract.CH_JOYSTICK, self.signed(contract.CH_JOYSTICK, self.joystick_msg(vx, vy, yaw_rate)))

    def pump(self, until, timeout_s: float = ANSWER_TIMEOUT_S) -> bool:
        deadline = time.monotonic() + timeout_s
        while not until():
            if time.monotonic() > deadline or self.proc.poll() is not None:
                return False
            self.lc.handle_timeout(10)
        return True

    # ---------------------------------------------------------------- lockstep exchange
    def step(self) -> joint_command_t:
        """Lockstep: publish IMU + state k, return the command answering k. Until the runtime is up (it
        subscribes after loading the artifact), unanswered states are re-sent under a new seq."""
        start_deadline = time.monotonic() + 30.0
        while True:
            self.seq += 1
            self.publish(contract.CH_IMU, self.imu_msg().encode())
            self.publish(contract.CH_JOINT_STATE, self.state_msg().encode())
            k = self.seq
            if self.pump(lambda: bool(self.cmds) and self.cmds[-1].state_seq == k,
                         ANSWER_TIMEOUT_S if self.started else 0.2):
                self.started = True
                return self.cmds[-1]
            if self.started or time.monotonic() > start_deadline or self.proc.poll() is not None:
                raise AssertionError(f"runtime did not answer state {k}: {self.stderr()}")

    def steps(self, n: int) -> list[joint_command_t]:
        return [self.step() for _ in range(n)]

    def until_mode(self, mode: str, max_ticks: int = 3000) -> int:
        for i in range(max_ticks):
            if self.step().mode == MODE[mode]:
                return i
        raise AssertionError(f"no {mode} within {max_ticks} ticks; last status: {self.last_status()}")

    def last_status(self, fresh: bool = True) -> controller_status_t:
        """The newest status; with fresh, tick (lockstep) or wait (realtime) until one more arrives."""
        if fresh:
            n = len(self.statuses)
            if self.lockstep:
                for _ in range(60):  # status every 50 ticks
                    self.step()
                    self.lc.handle_timeout(0)
                    if len(self.statuses) > n:
                        break
            self.pump(lambda: len(self.statuses) > n)
        assert self.statuses, "no T1_CONTROLLER_STATUS received"
        return self.statuses[-1]

    def stderr(self) -> str:
        if self.proc.poll() is None:
            return "(running)"
        return self.proc.communicate()[1][-2000:]

    def close(self) -> tuple[int, str]:
        return stop(self.proc)
