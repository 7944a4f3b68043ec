"""Closed loop over the real deployment path: t1-runtime (C++) + sim_hil in lockstep, over LCM, through
the emulated CAN buses. 20 s of sim time without a fault, and deterministic: two runs give the same
command stream byte for byte. Uses the shipped untrained student: this proves the plumbing and the safety
path, not a skill."""
from __future__ import annotations

from pathlib import Path

import pytest
from t1 import controller_status_t, joint_command_t

from messages import contract
from sim_hil.launch import ROOT, start_runtime, start_sim, stop
from sim_hil.lcmlog.eventlog import open_log

UNTRAINED_STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"

SIM_SECONDS = 20.0


def closed_loop_run(sim_seconds: float, log_path: Path, spawn: str = "fallen:62"):
    """(the T1_JOINT_CMD payloads, the decoded T1_CONTROLLER_STATUS) of one run, from the sim's LCM log: no
    Python subscriber keeps up with every message of a lockstep run at 10× real time on a loaded machine."""
    runtime = start_runtime(UNTRAINED_STUDENT, "--clock", "lockstep", "--autostart")
    sim = start_sim("--clock", "lockstep", "--spawn", spawn, "--seed", "62", "--duration", str(sim_seconds),
                    "--log", str(log_path))
    try:
        _, err = sim.communicate(timeout=300)
    finally:
        code, runtime_err = stop(runtime)
    assert sim.returncode == 0, f"sim failed: {err}"
    assert code == 0, f"runtime exit {code}: {runtime_err}"
    log = open_log(log_path)
    assert log.problems.messages(log_path) == []
    commands = [ev.data for ev, _ in log.messages[contract.CH_JOINT_CMD]]
    return commands, [m for _, m in log.messages[contract.CH_CONTROLLER_STATUS]]


@pytest.mark.slow
def test_runtime_and_sim_in_lockstep_run_20s_without_fault_and_deterministically(netns, tmp_path):
    first_cmds, first_status = closed_loop_run(SIM_SECONDS, tmp_path / "first.lcmlog")
    n_ticks = int(SIM_SECONDS / 0.002)
    decoded = [joint_command_t.decode(c) for c in first_cmds]
    # Every state was answered, in order (state_seq k answers state k).
    assert [c.state_seq for c in decoded] == list(range(n_ticks))
    assert first_status[-1].mode_name == "POLICY", first_status[-1].mode_name
    assert all(s.fault_bits & controller_status_t.LATCHED_FAULT_MASK == 0 for s in first_status), \
        [s.last_fault for s in first_status][-1]
    assert first_status[-1].policy_ticks > 0.8 * n_ticks / 10
    second_cmds, _ = closed_loop_run(SIM_SECONDS, tmp_path / "second.lcmlog")
    # utime in a command is the answered state's sim time, so equal streams mean equal trajectories.
    assert second_cmds == first_cmds
