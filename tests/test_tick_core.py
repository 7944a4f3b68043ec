"""The lockstep tick in C++ (sim_hil/core, the default) publishes exactly the states the Python tick
(--python-tick, the reference) does, bit for bit, fault-free and through every fault kind: dead motors, lost
and delayed frames inside the C++ tick; IMU noise and bias, frozen encoders and pushes by handing those ticks
to Python."""
from __future__ import annotations

import pytest

from common import model as t1model
from common import scenarios
from messages import contract
from tests.sim_harness import hold_pose, run_with_client

MODEL, _ = scenarios.build("flat", 0)
KP, KD = t1model.pd_gains(MODEL)
HOME = t1model.default_pose(MODEL)
EVERY_FAULT = ("dead:joint=Left_Knee_Pitch@0.1-0.3;drop:rate=0.2@0.2-0.5;delay:ticks=3@0.4-0.6;"
               "frozen:joint=14@0.55-0.7;imu_noise:gyro=0.05@0.65-0.75;imu_bias:accel=0.3@0.8-0.85;push:x=30@0.9")


@pytest.mark.parametrize("faults", ["", EVERY_FAULT], ids=["fault-free", "every-fault-kind"])
def test_the_cpp_tick_publishes_what_the_python_tick_does(netns, faults):
    streams = []
    for mode in ([], ["--python-tick"]):
        args = ["--clock", "lockstep", "--spawn", "fallen:3", *mode] + (["--faults", faults] if faults else [])
        imu: list[bytes] = []
        client, _, _ = run_with_client(args, hold_pose(HOME), KP, KD, duration_s=1.0,
                                       extra=lambda lc: lc.subscribe(contract.CH_IMU, lambda _c, d: imu.append(d)))
        streams.append((client.states, imu))
    for name, cpp, python in zip(("T1_JOINT_STATE", "T1_IMU"), *streams):
        assert len(cpp) == len(python) == 500, name
        first = next((k for k, (a, b) in enumerate(zip(cpp, python)) if a != b), None)
        assert first is None, f"{name} {first} differs between the C++ and the Python tick"


def test_ticks_between_status_messages_and_fault_edges_run_in_one_call(netns):
    """Simulator.advance batches the ticks that need nothing from Python up to the next status message or
    fault edge (the bit-for-bit test above runs the batches: the sim's run loop advances)."""
    from sim_hil.faults import FaultSchedule, parse_faults
    from sim_hil.sim import SimConfig, Simulator

    schedule = FaultSchedule(parse_faults("dead:joint=3@0.1-0.3;push:x=5@0.5"))
    assert [schedule.next_change_s(t) for t in (0.0, 0.1, 0.35, 0.5)] == [0.1, 0.3, 0.5, float("inf")]
    sim = Simulator(SimConfig(clock="lockstep", spawn="standing", lcm_url=contract.lcm_url(),
                              faults="dead:joint=3@0.1-0.3;drop:rate=0.5@0.4"))
    try:
        assert sim._batchable_ticks(1000) == 1           # until the first command: one tick at a time
        sim._commanded = True
        every = sim._status_every
        assert sim._batchable_ticks(1000) == min(every, 49) and sim._batchable_ticks(7) == 7   # dead starts at 0.1 s
        sim.data.time, sim.seq = 0.2, 100
        assert sim._batchable_ticks(1000) == min(every, 49)  # dead ends at 0.3 s: 50 ticks, the last at the edge
        sim.seq = 100 + every - 3
        assert sim._batchable_ticks(1000) == 3           # the status message ends a batch
        sim.data.time = 0.45
        assert sim._batchable_ticks(1000) == 1           # frames lost at random: drawn per tick, in Python
    finally:
        sim.close()
