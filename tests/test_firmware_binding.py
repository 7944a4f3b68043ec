"""Tests of the ctypes binding of firmware_like (sim_hil/firmware.py): protocol constants agree with the
contract, pack/unpack round trip, the batch step equals the documented formula, watchdog visible from
Python, bus model, and a micro-timing print (no timing assertion)."""
from __future__ import annotations

import time

import numpy as np
import pytest

from messages import contract
from sim_hil import firmware as fw
from sim_hil import firmware_buses as fwb

N = fw.NUM_MOTORS
ALL = fw.ALL_MOTORS_MASK


def _random_command(rng: np.random.Generator):
    span = fw.Q_MAX - fw.Q_MIN
    q_des = fw.Q_MIN + rng.uniform(0.0, 1.0, N) * span
    dq_des = rng.uniform(-1.0, 1.0, N) * fw.V_RANGE
    kp = rng.uniform(0.0, fw.KP_MAX, N)
    kd = rng.uniform(0.0, fw.KD_MAX, N)
    tau_ff = rng.uniform(-1.0, 1.0, N) * fw.T_RANGE
    return q_des, dq_des, kp, kd, tau_ff


def test_constants_match_contract():
    assert N == contract.NUM_JOINTS
    assert fw.MOTOR_NAMES == contract.JOINT_NAMES
    assert [fw.BUS_OF_MOTOR.count(b) for b in range(fw.NUM_BUSES)] == [6, 6, 8, 3]
    assert fw.BUS_NAMES == ("left_leg", "right_leg", "arms", "head_waist")
    assert fw.cmd_can_id(0) == 0x101 and fw.reply_can_id(22) == 0x217
    assert fw.TORQUE_LIMIT[contract.joint_index("Left_Knee_Pitch")] == 60.0
    assert fw.TORQUE_LIMIT[contract.joint_index("Right_Hip_Roll")] == 30.0
    assert fw.TORQUE_LIMIT[contract.joint_index("Left_Ankle_Roll")] == 15.0
    assert np.all(fw.TORQUE_LIMIT <= fw.T_RANGE)
    with pytest.raises(IndexError):
        fw.cmd_can_id(23)


def test_pack_unpack_round_trip():
    rng = np.random.default_rng(1)
    cmd = _random_command(rng)
    frames = fw.pack_commands(*cmd)
    assert len(frames) == N * 8
    back = fw.unpack_command(frames)
    steps = (8.0 / 65535, 2 * fw.V_RANGE / 4095, fw.KP_MAX / 4095, fw.KD_MAX / 4095, 2 * fw.T_RANGE / 4095)
    for sent, got, step in zip(cmd, back, steps):
        assert np.all(np.abs(got - sent) <= np.asarray(step) * 0.5 + 1e-6)
    # single frame through the per-motor form
    i = 14
    one = fw.unpack_command(frames[i * 8:(i + 1) * 8], i)
    assert np.allclose(one, [a[i] for a in back])
    # float32 and lists are accepted too
    assert fw.pack_commands(*(np.asarray(a, np.float32) for a in cmd)) == fw.pack_commands(
        *(np.asarray(a, np.float32).tolist() for a in cmd))


def test_pack_rejects_nonfinite_and_saturates():
    z = np.zeros(N)
    q = z.copy()
    q[3] = np.nan
    with pytest.raises(ValueError, match="Left_Shoulder_Roll"):
        fw.pack_commands(q, z, z, z, z)
    frames, ok = fw.pack_commands_masked(q, z, z, z, z)
    assert not ok[3] and ok.sum() == N - 1 and frames[24:32] == bytes(8)
    big = fw.pack_commands(np.full(N, 100.0), z, np.full(N, 1e9), z, np.full(N, -1e9))
    q_des, _, kp, _, tau = fw.unpack_command(big)
    assert np.all(q_des == fw.Q_MAX_RAD) and np.all(kp == fw.KP_MAX) and np.allclose(tau, -fw.T_RANGE)
    with pytest.raises(ValueError, match="23 values"):
        fw.pack_commands(np.zeros(5), z, z, z, z)


def test_batch_step_equals_formula():
    rng = np.random.default_rng(7)
    motors = fw.MotorArray()
    for trial in range(20):
        cmd = _random_command(rng)
        now = 1000 * (trial + 1)
        assert motors.receive_all(fw.pack_commands(*cmd), now) == 0
        q_des, dq_des, kp, kd, tau_ff = fw.unpack_command(fw.pack_commands(*cmd))  # what the motor sees
        # q strictly inside the soft stops so only the PD law acts
        q = fw.Q_MIN + rng.uniform(0.05, 0.95, N) * (fw.Q_MAX - fw.Q_MIN)
        dq = rng.uniform(-5.0, 5.0, N)
        tau = motors.step(q, dq, now + 500)
        expect = np.clip(kp * (q_des - q) + kd * (dq_des - dq) + tau_ff, -fw.TORQUE_LIMIT, fw.TORQUE_LIMIT)
        # the firmware computes in float32: tolerance relative to the torque scale
        assert np.allclose(tau, expect, rtol=1e-5, atol=1e-3 * fw.TORQUE_LIMIT.max())
        saturated = np.abs(kp * (q_des - q) + kd * (dq_des - dq) + tau_ff) > fw.TORQUE_LIMIT + 1e-3
        status = motors.status
        assert np.all((status[saturated] & fw.STATUS_OVER_LIMIT) != 0)


def test_watchdog_visible_through_python():
    motors = fw.MotorArray()
    z = np.zeros(N)
    assert np.all(motors.status & fw.STATUS_POWER_ON)
    dq = np.ones(N)
    assert np.allclose(motors.step(z, dq, 0), -fw.D_SAFE * dq, atol=1e-5)
    frames = fw.pack_commands(np.full(N, 0.0), z, np.full(N, 20.0), np.full(N, 1.0), z)
    motors.receive_all(frames, 0)
    assert np.all(motors.status == 0)
    motors.step(z, z, fw.WATCHDOG_US)  # exactly 50 ms: still following
    assert not np.any(motors.status & fw.STATUS_WATCHDOG)
    tau = motors.step(z, dq, fw.WATCHDOG_US + fw.BUS_CYCLE_US)
    assert np.all(motors.status & fw.STATUS_WATCHDOG)
    assert np.allclose(tau, -fw.D_SAFE * dq, atol=1e-5)
    # replies carry the status byte; a fresh command for motor 0 only clears its watchdog
    _, _, _, status = fw.unpack_replies(motors.replies(z, dq, tau))
    assert np.all(status & fw.STATUS_WATCHDOG)
    assert motors.receive(0, frames[:8], 60_000)
    motors.step(z, z, 61_000)
    st = motors.status
    assert st[0] == 0 and np.all(st[1:] & fw.STATUS_WATCHDOG)


def test_bad_frames_through_python():
    motors = fw.MotorArray()
    frames = fw.pack_commands(*(np.zeros(N) for _ in range(5)))
    assert not motors.receive(2, frames[:7], 0)  # wrong DLC
    assert not motors.receive(2, frames[:8], 0, can_id=fw.reply_can_id(2))  # wrong id
    assert motors.status[2] & fw.STATUS_BAD_FRAME
    corrupt = bytearray(motors.replies(np.zeros(N), np.zeros(N), np.zeros(N)))
    corrupt[5 * 8] = 99  # motor id byte of slot 5
    q, _, _, status = fw.unpack_replies(bytes(corrupt))
    assert np.isnan(q[5]) and status[5] == fw.STATUS_NO_REPLY and np.all(np.isfinite(np.delete(q, 5)))
    with pytest.raises(ValueError, match="184 bytes"):
        fw.unpack_replies(b"\x00" * 10)


def test_bus_model():
    bus = fwb.BusModel(2)
    assert bus.capacity_bits == 2000
    bus.begin_cycle(0)
    zeros = bytes(8)
    assert fw.can_frame_bits(0x101, zeros) == 126  # worked example of firmware_like/tests/test_can_bus.c
    on_time = [bus.submit(0x101, zeros) for _ in range(16)]
    assert on_time == [True] * 15 + [False] and bus.frames_late == 1
    bus.begin_cycle(2000)
    assert bus.utilisation == pytest.approx(2016 / 2000)
    with pytest.raises(ValueError, match="arms"):
        bus.submit(0x900, zeros)
    with pytest.raises(IndexError):
        fwb.BusModel(4)


def test_bus_array_cycle_and_timing():
    rng = np.random.default_rng(3)
    motors, buses = fw.MotorArray(), fwb.BusArray()
    cmd = _random_command(rng)
    q, dq = np.zeros(N), np.zeros(N)
    ticks = 2000
    t0 = time.perf_counter()
    for k in range(ticks):
        now = k * fw.BUS_CYCLE_US
        frames = fw.pack_commands(*cmd)
        motors.receive_all(frames, now)
        tau = motors.step(q, dq, now)
        replies = motors.replies(q, dq, tau)
        cmd_ok, rep_ok = buses.cycle(now, frames, replies)
        q, dq, _, _ = fw.unpack_replies(replies)
    per_tick_us = (time.perf_counter() - t0) / ticks * 1e6
    assert cmd_ok.all()
    util = buses.utilisation
    print(f"\nfirmware binding: {per_tick_us:.1f} us per tick (pack, receive, step, replies, bus cycle, "
          f"unpack); bus utilisation {dict(zip(fw.BUS_NAMES, np.round(util, 3)))}; "
          f"late frames {buses.frames_late.tolist()}")
    assert np.all(util > 0.3) and np.all(util < 1.2)
