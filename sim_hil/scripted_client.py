"""A scripted joint-space client of the simulated T1 (no policy): answers every T1_JOINT_STATE with a PD
command toward a target pose given as a function of time. Used by the tests, `make bench`, and by the
demo until a trained policy exists. Lockstep-correct: each command carries state_seq = the state's seq."""
from __future__ import annotations

import time
from typing import Callable

import lcm
import numpy as np
from t1 import joint_command_t, joint_state_t

from messages import contract

N = contract.NUM_JOINTS
TargetFn = Callable[[float, np.ndarray], np.ndarray]   # (sim time [s], measured q [rad]) -> q_des [rad]


class ScriptedClient:
    def __init__(self, target: TargetFn, kp: np.ndarray, kd: np.ndarray, url: str | None = None,
                 record_states: bool = False, stop_after_s: float | None = None):
        self.lc = lcm.LCM(url or contract.lcm_url())
        self.target, self.kp, self.kd = target, np.asarray(kp, float), np.asarray(kd, float)
        self.stop_after_s = stop_after_s          # stop answering after this sim time (watchdog tests)
        self.states: list[bytes] = []             # raw T1_JOINT_STATE payloads, if recording
        self.wall: list[float] = []               # wall time [s] each recorded state arrived
        self.record_states = record_states
        self.last_state: joint_state_t | None = None
        self.history: list[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = []  # (t, q, dq, q_des)
        self.cmd_seq = 0
        self.lc.subscribe(contract.CH_JOINT_STATE, self._on_state)

    def _on_state(self, _channel: str, payload: bytes) -> None:
        state = joint_state_t.decode(payload)
        self.last_state = state
        if self.record_states:
            self.states.append(payload)
            self.wall.append(time.perf_counter())
        t = state.utime * 1e-6
        if self.stop_after_s is not None and t >= self.stop_after_s:
            return
        q = np.asarray(state.q)
        q_des = np.asarray(self.target(t, q), dtype=float)
        self.history.append((t, q, np.asarray(state.dq), q_des))
        cmd = joint_command_t()
        cmd.utime, cmd.seq, cmd.state_seq = state.utime, self.cmd_seq, state.seq
        cmd.q_des, cmd.dq_des = q_des.tolist(), [0.0] * N
        cmd.kp, cmd.kd, cmd.tau_ff = self.kp.tolist(), self.kd.tolist(), [0.0] * N
        cmd.mode = joint_command_t.MODE_POLICY
        self.cmd_seq += 1
        self.lc.publish(contract.CH_JOINT_CMD, cmd.encode())

    def spin(self, until: Callable[[], bool], timeout_s: float) -> None:
        """Handle messages until `until()` is true or timeout_s of wall time pass."""
        deadline = time.monotonic() + timeout_s
        while not until() and time.monotonic() < deadline:
            self.lc.handle_timeout(50)


def ramp_to(q_goal: np.ndarray, duration_s: float, start_s: float = 0.0) -> TargetFn:
    """Linear ramp from the pose measured at start_s to q_goal over duration_s, then hold."""
    q_start: list[np.ndarray] = []

    def target(t: float, q: np.ndarray) -> np.ndarray:
        if not q_start:
            if t < start_s:
                return q
            q_start.append(q.copy())
        alpha = np.clip((t - start_s) / duration_s, 0.0, 1.0)
        return (1 - alpha) * q_start[0] + alpha * q_goal

    return target
