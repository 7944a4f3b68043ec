"""LCM side of the simulator: publishes T1_IMU / T1_JOINT_STATE / T1_SIM_STATUS, receives T1_JOINT_CMD.

A command is validated before it can reach the bus: undecodable payloads (wrong type, wrong sizes) and
commands with non-finite or out-of-range fields are counted and dropped with a reason, never a crash.
"""
from __future__ import annotations

import select
import sys

import lcm
import numpy as np
from t1 import imu_t, joint_command_t, joint_state_t, sim_status_t

from messages import contract
from sim_hil import firmware as fw

N = contract.NUM_JOINTS


FIELDS = ("q_des", "dq_des", "kp", "kd", "tau_ff")


def command_fields(msg: joint_command_t) -> tuple[np.ndarray | None, str | None]:
    """The command's fields as one float64[5, N] array (FIELDS order), or None and the reason it is
    unusable. Gains must be inside the frame's encodable range."""
    for name in FIELDS:
        if len(getattr(msg, name)) != N:
            return None, f"{name} has {len(getattr(msg, name))} values, expected {N}"
    fields = np.array([getattr(msg, name) for name in FIELDS], dtype=np.float64)
    finite = np.isfinite(fields).all(axis=1)
    if not finite.all():
        return None, f"{FIELDS[int(np.argmin(finite))]} contains NaN or Inf"
    kp, kd = fields[2], fields[3]
    if kp.min() < 0 or kp.max() > fw.KP_MAX:
        return None, f"kp outside [0, {fw.KP_MAX}] N·m/rad"
    if kd.min() < 0 or kd.max() > fw.KD_MAX:
        return None, f"kd outside [0, {fw.KD_MAX}] N·m·s/rad"
    return fields, None


class LcmBridge:
    def __init__(self, url: str):
        try:
            self.lc = lcm.LCM(url)
        except (RuntimeError, OSError) as exc:
            raise RuntimeError(f"cannot open LCM at '{url}': {exc} (run inside tools/netns)") from exc
        self.url = url
        self.latest: joint_command_t | None = None   # newest valid command
        self.latest_frames: bytes | None = None      # ... already packed into 23 CAN command frames
        self.cmds_received = 0
        self.cmds_dropped = 0
        self.last_drop_reason = ""
        self._reported = 0
        self.lc.subscribe(contract.CH_JOINT_CMD, self._on_command)
        self._fd = self.lc.fileno()

    def _on_command(self, _channel: str, payload: bytes) -> None:
        try:
            msg = joint_command_t.decode(payload)
            fields, reason = command_fields(msg)
        except ValueError as exc:              # wrong fingerprint / truncated payload
            msg, reason = None, f"undecodable T1_JOINT_CMD ({exc})"
        if reason is not None:
            self.cmds_dropped += 1
            self.last_drop_reason = reason
            if self._reported < 5:             # say why, without flooding the terminal at 500 Hz
                print(f"sim_hil: dropped command: {reason}", file=sys.stderr)
                self._reported += 1
            return
        self.cmds_received += 1
        self.latest = msg
        self.latest_frames = fw.pack_commands(*fields)

    def poll(self, timeout_s: float) -> None:
        """Handle incoming messages for up to timeout_s (0 = only what is already queued). Waits on the
        LCM socket with select, which times out to the microsecond (LCM's own wait counts whole ms)."""
        while self.lc.handle_timeout(0) > 0:       # drain what is queued
            pass
        if timeout_s > 0 and select.select([self._fd], [], [], timeout_s)[0]:
            self.lc.handle()

    def wait_for_answer(self, state_seq: int, timeout_s: float, clock) -> bool:
        """Lockstep: handle messages until the command answering state_seq arrives (True) or timeout."""
        deadline = clock() + timeout_s
        while self.latest is None or self.latest.state_seq < state_seq:
            remaining = deadline - clock()
            if remaining <= 0:
                return False
            self.lc.handle_timeout(max(1, int(remaining * 1000)))
        return True

    def publish_state(self, utime: int, seq: int, quat, gyro, accel, q, dq, tau, status) -> None:
        imu = imu_t()
        imu.utime, imu.seq = utime, seq
        imu.quat, imu.gyro, imu.accel = np.asarray(quat, float).tolist(), np.asarray(gyro, float).tolist(), \
            np.asarray(accel, float).tolist()
        js = joint_state_t()
        js.utime, js.seq = utime, seq
        js.q, js.dq, js.tau_est = q.tolist(), dq.tolist(), tau.tolist()
        js.motor_status = status.tolist()
        self.lc.publish(contract.CH_IMU, imu.encode())
        self.lc.publish(contract.CH_JOINT_STATE, js.encode())

    def publish_status(self, status: sim_status_t) -> None:
        self.lc.publish(contract.CH_SIM_STATUS, status.encode())
