"""Every fault kind changes the published messages the way sim_hil/faults.py says it does, and
malformed commands are counted and dropped. Each test compares against a fault-free stretch."""
from __future__ import annotations

import lcm  # noqa: F401
import numpy as np
import pytest
from t1 import imu_t, joint_command_t, joint_state_t

from common import model as t1model
from common import scenarios
from messages import contract
from sim_hil import firmware as fw
from sim_hil.faults import FaultSpecError, parse_faults
from sim_hil.motor_bus import NO_REPLY
from tests.sim_harness import hold_pose, run_with_client

MODEL, _ = scenarios.build("flat", 0)
KP, KD = t1model.pd_gains(MODEL)
HOME = t1model.default_pose(MODEL)
BASE = ["--clock", "lockstep", "--spawn", "standing", "--lockstep-timeout", "0.005"]
HEAD = contract.joint_index("AAHead_yaw")


def _run(faults: str, duration_s=0.6, target=None, extra=None):
    client, status, _ = run_with_client(BASE + ["--faults", faults], target or hold_pose(HOME), KP, KD,
                                        duration_s=duration_s, extra=extra)
    seq = [joint_state_t.decode(p) for p in client.states]
    t = np.array([s.utime * 1e-6 for s in seq])
    return seq, t, status


def test_fault_spec_errors_name_the_problem():
    for spec, needle in (("warp:speed=9", "warp"), ("drop", "rate"), ("delay:ticks=1.5", "ticks"),
                         ("frozen:joint=99", "99"), ("imu_noise:gyro=-1", ">= 0"), ("push:x=1@3-2", "START"),
                         ("press:joint=Waist", "tau"), ("press:tau=5", "joint"), ("load", "at least one")):
        with pytest.raises(FaultSpecError, match=needle):
            parse_faults(spec)
    assert [f.kind for f in parse_faults("drop:rate=0.1@1;push:x=5@2")] == ["drop", "push"]


def test_frame_drop_loses_replies_and_starves_motors(netns):
    seq, t, _ = _run("drop:rate=1.0@0.2")
    before = [s for s, ti in zip(seq, t) if ti < 0.2]
    after = [s for s, ti in zip(seq, t) if ti > 0.3]
    assert not any(st & NO_REPLY for s in before for st in s.motor_status)
    assert all(st & NO_REPLY for s in after for st in s.motor_status)
    assert after[0].q == after[-1].q            # no replies: the host's view is frozen


def test_frame_delay_postpones_the_response(netns):
    step = HOME.copy()
    step[HEAD] += 0.4

    def target(ti, _q):
        return step if ti >= 0.1 else HOME

    def onset(faults):
        seq, t, _ = _run(faults, duration_s=0.3, target=target)
        moved = [ti for s, ti in zip(seq, t) if abs(s.q[HEAD] - HOME[HEAD]) > 0.01]
        return moved[0]
    # Each bus cycle is 2 ms: 5 cycles of delay shift the onset by 10 ms.
    assert onset("delay:ticks=5@0") - onset("delay:ticks=1@1000") == pytest.approx(0.010, abs=0.0025)


def test_dead_motor_goes_silent_and_limp(netns):
    joint = contract.joint_index("Left_Elbow_Yaw")
    seq, t, _ = _run(f"dead:joint={joint}@0.2")
    after = [s for s, ti in zip(seq, t) if ti > 0.25]
    assert all(s.motor_status[joint] & NO_REPLY for s in after)
    assert not any(s.motor_status[j] & NO_REPLY for s in after for j in range(23) if j != joint)


def test_frozen_encoder_reports_a_constant_position(netns):
    joint = HEAD

    def moving(ti, _q):
        return HOME + 0.3 * np.sin(2 * np.pi * 2 * ti) * (np.arange(23) == joint)
    seq, t, _ = _run(f"frozen:joint={joint}@0.2", target=moving)
    during = np.array([s.q[joint] for s, ti in zip(seq, t) if ti > 0.21])
    before = np.array([s.q[joint] for s, ti in zip(seq, t) if ti < 0.2])
    assert np.ptp(before) > 0.05 and np.ptp(during) == 0.0
    # what a frozen encoder freezes: dq is differentiated from it (reads 0); tau_est is the motor's current, the
    # honest torque of its PD law on the stuck reading, which changes as the target moves
    dq = np.array([s.dq[joint] for s, ti in zip(seq, t) if ti > 0.21])
    tau = np.array([s.tau_est[joint] for s, ti in zip(seq, t) if ti > 0.21])
    assert np.abs(dq).max() <= fw.V_RANGE[joint] / (2 ** 12 - 1) and np.ptp(tau) > 1.0


def test_a_load_holds_the_trunk_down_while_it_lasts(netns):
    _, _, free = _run("", duration_s=0.5)
    _, _, held = _run("load:z=-2000@0.1-0.3", duration_s=0.5)

    def z(status, at):
        return {round(s.utime * 1e-6, 1): s.base_pos[2] for s in status.msgs}[at]
    assert z(held, 0.3) < z(free, 0.3) - 0.01        # pressed down, then released
    assert "load" in next(s.active_faults for s in held.msgs if 0.1 < s.utime * 1e-6 < 0.3)


def test_a_press_holds_a_joint_against_its_stop(netns):
    joint = contract.joint_index("Left_Elbow_Yaw")     # home -0.4 rad, stop at 0
    seq, t, _ = _run(f"press:joint={joint},tau=25@0.1", duration_s=0.6)
    q = np.array([s.q[joint] for s in seq])
    assert q[t < 0.1].max() < fw.Q_MAX[joint] - 0.3 and q[t > 0.4].min() > fw.Q_MAX[joint] - 0.01
    tau = np.array([s.tau_est for s, ti in zip(seq, t) if ti > 0.2])   # each motor still reports its own torque
    assert (np.ptp(tau, axis=1) > 1.0).all() and not np.isclose(tau[:, joint], 25.0).any()


def test_imu_noise_and_bias_show_in_the_imu_stream(netns):
    def gyro_stream(faults):
        imus: list[imu_t] = []

        def sub(lc):
            return lc.subscribe(contract.CH_IMU, lambda _c, d: imus.append(imu_t.decode(d)))
        _run(faults, duration_s=0.6, extra=sub)
        return np.array([m.utime * 1e-6 for m in imus]), np.array([m.gyro for m in imus])
    # Lockstep is deterministic, so the fault-free run is the exact truth to subtract.
    t, clean = gyro_stream("")
    t2, faulty = gyro_stream("imu_bias:gyro=0.5,accel=2.0@0.3;imu_noise:gyro=0.2@0.3")
    assert np.array_equal(t, t2)
    diff = faulty - clean
    assert np.all(diff[t < 0.3] == 0.0)
    during = diff[t >= 0.3]
    assert np.abs(during.mean(axis=0) - 0.5).max() < 0.05          # bias 0.5 rad/s on every axis
    assert 0.17 < (during - during.mean(axis=0)).std() < 0.23      # noise std 0.2 rad/s


def test_push_kicks_the_trunk(netns):
    _, _, status = _run("push:x=25@0.3", duration_s=0.5)
    vx = {round(s.utime * 1e-6, 1): s.base_lin_vel[0] for s in status.msgs}
    # 25 N·s on a 31.6 kg robot: the trunk speeds up by roughly 0.5-0.8 m/s right after the push.
    assert vx[0.4] - vx[0.3] > 0.3


def test_malformed_commands_are_counted_and_dropped(netns):
    sent = []

    def inject(lc):
        bad = joint_command_t()
        bad.q_des = [float("nan")] * 23
        bad.dq_des = bad.kp = bad.kd = bad.tau_ff = [0.0] * 23
        lc.publish(contract.CH_JOINT_CMD, bad.encode())
        lc.publish(contract.CH_JOINT_CMD, b"\x00garbage, not an LCM message")
        over = joint_command_t()
        over.q_des = over.dq_des = over.tau_ff = [0.0] * 23
        over.kp, over.kd = [fw.KP_MAX * 2] * 23, [0.0] * 23
        lc.publish(contract.CH_JOINT_CMD, over.encode())

    holder = {}

    def target(ti, _q):                       # inject once the sim is up and listening
        if ti >= 0.1 and not sent:
            sent.append(ti)
            inject(holder["lc"])
        return HOME

    _, _, status = _run("", duration_s=0.4, target=target, extra=lambda lc: holder.setdefault("lc", lc))
    assert sent and status.msgs[-1].cmds_dropped == 3
