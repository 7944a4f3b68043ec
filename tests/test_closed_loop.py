"""Closed loop over the real deployment path: t1-runtime (C++) + sim_hil in lockstep, over LCM, through
the emulated CAN buses. 20 s of sim time without a fault, and deterministic: two runs give the same
command stream byte for byte. Uses the shipped untrained student: this proves the plumbing and the safety
path, not a skill."""
from __future__ import annotations

import time

import lcm
import pytest
from t1 import controller_status_t, joint_command_t

from messages import contract
from sim_hil.launch import ROOT, start_runtime, start_sim, stop

UNTRAINED_STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"

SIM_SECONDS = 20.0


def closed_loop_run(sim_seconds: float, spawn: str = "fallen:62"):
    lc = lcm.LCM(contract.lcm_url())
    commands: list[bytes] = []
    status: list[controller_status_t] = []
    lc.subscribe(contract.CH_JOINT_CMD, lambda _c, d: commands.append(d))
    lc.subscribe(contract.CH_CONTROLLER_STATUS, lambda _c, d: status.append(controller_status_t.decode(d)))
    runtime = start_runtime(UNTRAINED_STUDENT, "--clock", "lockstep", "--autostart")
    sim = start_sim("--clock", "lockstep", "--spawn", spawn, "--seed", "62", "--duration", str(sim_seconds))
    deadline = time.monotonic() + 300
    while sim.poll() is None and time.monotonic() < deadline:
        lc.handle_timeout(20)
    while lc.handle_timeout(50) > 0:
        pass
    assert sim.poll() == 0, f"sim failed: {sim.communicate()[1] if sim.poll() is not None else 'timeout'}"
    code, err = stop(runtime)
    assert code == 0, f"runtime exit {code}: {err}"
    return commands, status


@pytest.mark.slow
def test_runtime_and_sim_in_lockstep_run_20s_without_fault_and_deterministically(netns):
    first_cmds, first_status = closed_loop_run(SIM_SECONDS)
    n_ticks = int(SIM_SECONDS / 0.002)
    decoded = [joint_command_t.decode(c) for c in first_cmds]
    # Every state was answered, in order (state_seq k answers state k).
    assert [c.state_seq for c in decoded] == list(range(n_ticks))
    assert first_status[-1].mode_name == "POLICY", first_status[-1].mode_name
    assert all(s.fault_bits & controller_status_t.LATCHED_FAULT_MASK == 0 for s in first_status), [s.last_fault for s in first_status][-1]
    assert first_status[-1].policy_ticks > 0.8 * n_ticks / 10
    second_cmds, _ = closed_loop_run(SIM_SECONDS)
    # utime in a command is the answered state's sim time, so equal streams mean equal trajectories.
    assert second_cmds == first_cmds
