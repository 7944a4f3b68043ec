"""DDS side of the simulator (`python -m sim_hil --dds`): the simulated T1 in the real robot's own topics.

LowState_ out on rt/low_state (IMU roll/pitch/yaw, gyro, acc; the 23 serial motor states from the motor
reply frames), LowCmd_ in from rt/joint_ctrl (SERIAL, 23 MotorCmd_) to the motor bus. Same interface as
LcmBridge, so the simulator's tick does not know which one it drives; T1_SIM_STATUS (simulator truth, no
robot has it) stays on LCM. Types: messages/dds_types.py, built from messages/dds/booster_low.idl.

A LowCmd_ is validated before it reaches the bus, like a joint_command_t: wrong cmd_type, wrong motor
count, non-finite numbers or gains outside the frame's range are counted and dropped with a reason.

Lockstep without sequence numbers: LowState_ has none, so "the command answering state k" is the first
LowCmd_ that arrives after state k was written (the runtime answers each state exactly once). Until the
first answer DDS discovery may still be matching, so the first state is re-sent until one arrives; then
the answers to the copies are let through before the clock starts (handshake below).
"""
from __future__ import annotations

import math
import sys

import lcm
import numpy as np
from cyclonedds.core import InstanceState, Policy, Qos, ReadCondition, SampleState, ViewState, WaitSet
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader, InvalidSample
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from t1 import sim_status_t

from messages import contract, dds_types
from sim_hil import firmware as fw

N = contract.NUM_JOINTS
DDS = contract.DDS
HANDSHAKE_RESEND_S = 0.05   # re-send the first state this often until the client answers [s]
HANDSHAKE_SETTLE_S = 0.2    # then wait this long without a new answer before the clock starts [s]
REPORT_DROPS = 5            # drop reasons printed, then only counted (500 Hz would flood the terminal)


def rpy_from_quat(quat_wxyz) -> tuple[float, float, float]:
    """Z-Y-X Euler angles (roll, pitch, yaw) of R = Rz(yaw) Ry(pitch) Rx(roll), the Booster IMU's
    convention as the runtime reads it (runtime/include/t1rt/policy.hpp: quat_from_rpy)."""
    w, x, y, z = (float(v) for v in quat_wxyz)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def validate_low_cmd(msg) -> str | None:
    """Reason the LowCmd_ is unusable, or None."""
    if msg.cmd_type.value != DDS["cmd_type_serial"]:
        return f"cmd_type {msg.cmd_type} is not SERIAL ({DDS['cmd_type_serial']}): the sim models serial joints"
    if len(msg.motor_cmd) != N:
        return f"motor_cmd has {len(msg.motor_cmd)} entries, expected {N}"
    for name in ("q", "dq", "tau", "kp", "kd"):
        if not all(math.isfinite(getattr(m, name)) for m in msg.motor_cmd):
            return f"motor_cmd {name} contains NaN or Inf"
    if not all(0 <= m.kp <= fw.KP_MAX for m in msg.motor_cmd):
        return f"kp outside [0, {fw.KP_MAX}] N·m/rad"
    if not all(0 <= m.kd <= fw.KD_MAX for m in msg.motor_cmd):
        return f"kd outside [0, {fw.KD_MAX}] N·m·s/rad"
    return None


def dds_qos(reliable: bool) -> Qos:
    """Newest sample only. Readers ask best effort, which matches a reliable or a best-effort peer."""
    reliability = Policy.Reliability.Reliable(duration(milliseconds=100)) if reliable else Policy.Reliability.BestEffort
    return Qos(reliability, Policy.History.KeepLast(1))


class DdsBridge:
    def __init__(self, url: str, domain_id: int = DDS["domain_id"]):
        try:
            self.lc = lcm.LCM(url)   # T1_SIM_STATUS (and the joystick of sim_hil.eval) stay on LCM
        except (RuntimeError, OSError) as exc:
            raise RuntimeError(f"cannot open LCM at '{url}': {exc} (run inside tools/netns)") from exc
        self.url = f"DDS domain {domain_id} ({DDS['state_topic']} out, {DDS['command_topic']} in) + LCM status {url}"
        self.command_source = f"{DDS['command_topic']} from a controller on DDS domain {domain_id}"
        self.participant = DomainParticipant(domain_id)
        state_topic = Topic(self.participant, DDS["state_topic"], dds_types.LowState)
        cmd_topic = Topic(self.participant, DDS["command_topic"], dds_types.LowCmd)
        self.writer = DataWriter(self.participant, state_topic, qos=dds_qos(reliable=True))
        self.reader = DataReader(self.participant, cmd_topic, qos=dds_qos(reliable=False))
        self.waitset = WaitSet(self.participant)
        self.waitset.attach(ReadCondition(self.reader, ViewState.Any | InstanceState.Any | SampleState.NotRead))
        self.latest = None                  # newest valid LowCmd_
        self.latest_frames: bytes | None = None
        self._lcm_subscribed = False        # Python LCM subscriptions (the live view's): poll handles lc too
        self.cmds_received = 0
        self.cmds_dropped = 0
        self.last_drop_reason = ""
        self._reported = 0
        self._answer_mark = 0               # cmds_received when the newest state was written
        self._last_state = None
        # MotorState_.lost as the runtime reads it (messages/dds/booster_low.idl): replies each motor missed
        self._lost = np.zeros(N, dtype=np.uint32)

    # ---- commands in ---------------------------------------------------------------------------------
    def _take(self) -> int:
        n = 0
        for msg in self.reader.take(N=64):
            if isinstance(msg, InvalidSample):   # a writer went away (unregister / dispose): no command in it
                continue
            n += 1
            reason = validate_low_cmd(msg)
            if reason is not None:
                self.cmds_dropped += 1
                self.last_drop_reason = reason
                if self._reported < REPORT_DROPS:
                    print(f"sim_hil: dropped LowCmd_: {reason}", file=sys.stderr)
                    self._reported += 1
                continue
            self.cmds_received += 1
            self.latest = msg
            m = msg.motor_cmd
            self.latest_frames = fw.pack_commands(np.array([c.q for c in m]), np.array([c.dq for c in m]),
                                                  np.array([c.kp for c in m]), np.array([c.kd for c in m]),
                                                  np.array([c.tau for c in m]))
        return n

    def _wait(self, timeout_s: float) -> None:
        if timeout_s > 0:
            self.waitset.wait(duration(microseconds=max(1, int(timeout_s * 1e6))))

    def take_frames(self) -> bytes | None:
        """The newest valid command's 23 CAN frames, once: a command goes on the bus once, as on the robot."""
        frames, self.latest_frames = self.latest_frames, None
        return frames

    def subscribe(self, channel: str, handler) -> None:
        """A Python LCM subscription beside the DDS link (the live view's), handled by poll."""
        self.lc.subscribe(channel, handler)
        self._lcm_subscribed = True

    def close(self) -> None:
        """Nothing to release by hand: the DDS entities go with the participant when the bridge is dropped."""

    def poll(self, timeout_s: float) -> None:
        """Handle incoming commands for up to timeout_s (0 = only what is already queued)."""
        if self._lcm_subscribed:
            while self.lc.handle_timeout(0) > 0:
                pass
        if self._take() == 0 and timeout_s > 0:
            self._wait(timeout_s)
            self._take()

    def wait_for_answer(self, state_seq: int, timeout_s: float, clock) -> bool:
        """Lockstep: the first LowCmd_ written after the newest state answers it (True), or timeout."""
        deadline = clock() + timeout_s
        if self.latest is None:
            return self._handshake(deadline, clock)
        while self.cmds_received <= self._answer_mark:
            remaining = deadline - clock()
            if remaining <= 0:
                return False
            self.poll(remaining)
        return True

    def _handshake(self, deadline: float, clock) -> bool:
        while self.latest is None:
            if clock() > deadline:
                return False
            self.poll(HANDSHAKE_RESEND_S)
            if self.latest is None and self._last_state is not None:
                self.writer.write(self._last_state)      # discovery may have missed the first copy
        settle_until = clock() + HANDSHAKE_SETTLE_S
        while clock() < settle_until:                    # answers to the re-sent copies: absorb them
            before = self.cmds_received
            self.poll(settle_until - clock())
            if self.cmds_received > before:
                settle_until = clock() + HANDSHAKE_SETTLE_S
        return True

    # ---- state out -----------------------------------------------------------------------------------
    def publish_state(self, utime: int, seq: int, quat, gyro, accel, q, dq, tau, status) -> None:
        """LowState_ from the IMU and the motor replies. utime / seq / firmware status bits have no field
        in LowState_ (the robot sends neither): the runtime numbers samples by arrival. The host's NO_REPLY
        bit becomes what the robot has instead, a per-motor count of missed replies in `lost`."""
        imu = dds_types.ImuState(rpy=list(rpy_from_quat(quat)), gyro=[float(v) for v in gyro],
                                 acc=[float(v) for v in accel])
        self._lost += (np.asarray(status) & fw.STATUS_HOST_NO_REPLY) != 0   # uint32: wraps as on the robot
        motors = [dds_types.MotorState(mode=0, q=float(q[i]), dq=float(dq[i]), ddq=0.0, tau_est=float(tau[i]),
                                       temperature=0, lost=int(self._lost[i]), reserve=[0, 0]) for i in range(N)]
        self._last_state = dds_types.LowState(imu_state=imu, motor_state_parallel=[], motor_state_serial=motors)
        self._answer_mark = self.cmds_received
        self.writer.write(self._last_state)

    def publish_status(self, status: sim_status_t) -> None:
        self.lc.publish(contract.CH_SIM_STATUS, status.encode())

    def matched_clients(self) -> int:
        """State readers currently matched (for start-up diagnostics)."""
        return len(self.writer.get_matched_subscriptions())
