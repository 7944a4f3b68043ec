"""LCM side of the simulator: publishes T1_IMU / T1_JOINT_STATE / T1_SIM_STATUS, receives T1_JOINT_CMD.

The state and command path is the C++ robot link (sim_hil/core/robot_link.cpp, through sim_hil/tick_core):
a command is validated before it can reach the bus (undecodable payloads, non-finite fields, gains outside
the frame's range are counted and dropped with a reason, never a crash) and packed into the 23 CAN command
frames at once. In lockstep the simulator's C++ tick uses the same link without returning to Python. A
Python LCM handle (`lc`) stays for the status message, for whoever publishes beside the sim (the evaluation's
joystick) and for subscriptions made through `subscribe` (the live view's).
"""
from __future__ import annotations

import lcm
from t1 import joint_command_t, sim_status_t

from messages import contract
from sim_hil import tick_core


class LcmBridge:
    def __init__(self, url: str):
        try:
            self.lc = lcm.LCM(url)
        except (RuntimeError, OSError) as exc:
            raise RuntimeError(f"cannot open LCM at '{url}': {exc} (run inside tools/netns)") from exc
        self.core = tick_core.Link(url)
        self.url = url
        self.command_source = f"{contract.CH_JOINT_CMD} from a controller on {url}"   # what lockstep waits for
        self._subscribed = False                # Python subscriptions on lc: then poll handles lc too
        self._latest: tuple[int, joint_command_t | None] = (0, None)

    # ---- commands ------------------------------------------------------------------------------------
    @property
    def latest(self) -> joint_command_t | None:
        """The newest valid command (decoded once per new command)."""
        received = self.cmds_received
        if received != self._latest[0]:
            payload = self.core.latest_payload()
            self._latest = (received, None if payload is None else joint_command_t.decode(payload))
        return self._latest[1]

    @property
    def cmds_received(self) -> int:
        return self.core.counters()[0]

    @property
    def cmds_dropped(self) -> int:
        return self.core.counters()[1]

    @property
    def last_drop_reason(self) -> str:
        return self.core.last_drop_reason()

    def take_frames(self) -> bytes | None:
        """The newest valid command's 23 CAN frames, once: a command goes on the bus once, as on the robot."""
        return self.core.take_frames()

    def poll(self, timeout_s: float) -> None:
        """Handle incoming commands for up to timeout_s (0 = only what is already queued)."""
        if self._subscribed:
            while self.lc.handle_timeout(0) > 0:
                pass
        self.core.poll(timeout_s)

    def wait_for_answer(self, state_seq: int, timeout_s: float, clock=None) -> bool:
        """Lockstep: handle commands until the one answering state_seq arrives (True) or timeout."""
        answered = self.core.wait_for_answer(state_seq, timeout_s)
        if self._subscribed:
            while self.lc.handle_timeout(0) > 0:
                pass
        return answered

    def subscribe(self, channel: str, handler) -> None:
        """A Python subscription beside the link (handled by poll / wait_for_answer)."""
        self.lc.subscribe(channel, handler)
        self._subscribed = True

    # ---- state ---------------------------------------------------------------------------------------
    def publish_state(self, utime: int, seq: int, quat, gyro, accel, q, dq, tau, status) -> None:
        self.core.publish_state(utime, seq, quat, gyro, accel, q, dq, tau, status)

    def sign_state(self, sender) -> None:
        """Sign every state from now on with the robot key's sender (messages/auth.py), in the C++ link."""
        self.core.sign_state(sender)

    def publish_status(self, status: sim_status_t) -> None:
        self.lc.publish(contract.CH_SIM_STATUS, status.encode())

    def close(self) -> None:
        self.core.close()
