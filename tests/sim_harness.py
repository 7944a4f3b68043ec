"""Run the simulator as a separate process against an in-test scripted client (the real deployment
shape: two processes talking LCM inside the project namespace)."""
from __future__ import annotations

import time

import lcm
import numpy as np
from t1 import sim_status_t

from messages import contract
from sim_hil.launch import start_sim
from sim_hil.scripted_client import ScriptedClient

__all__ = ["start_sim", "run_with_client", "hold_pose", "StatusRecorder"]


class StatusRecorder:
    def __init__(self, lc: lcm.LCM):
        self.msgs: list[sim_status_t] = []
        lc.subscribe(contract.CH_SIM_STATUS, lambda _c, d: self.msgs.append(sim_status_t.decode(d)))


def run_with_client(sim_args: list[str], target, kp, kd, duration_s: float, timeout_s: float = 120.0,
                    stop_after_s: float | None = None, extra=None):
    """Start the sim, answer its states until it exits; returns (client, status recorder, proc)."""
    client = ScriptedClient(target, kp, kd, record_states=True, stop_after_s=stop_after_s)
    status = StatusRecorder(client.lc)
    if extra is not None:
        extra(client.lc)
    proc = start_sim(*sim_args, "--duration", str(duration_s))
    deadline = time.monotonic() + timeout_s
    while proc.poll() is None and time.monotonic() < deadline:
        client.lc.handle_timeout(20)
    while client.lc.handle_timeout(0) > 0:
        pass
    if proc.poll() is None:
        proc.kill()
        raise AssertionError(f"sim did not finish within {timeout_s} s")
    out, err = proc.communicate()
    assert proc.returncode == 0, f"sim exited {proc.returncode}: {err}"
    return client, status, proc


def hold_pose(q: np.ndarray):
    return lambda _t, _q: q
