"""The simulator's two carriers of the bus frames agree: firmware_like's host link in C (`direct`, the
default) gives the host the same joint state, status bits and late-frame counts as the python-can buses,
tick for tick, with delayed commands overflowing the cycle and a motor off the bus."""
from __future__ import annotations

import numpy as np
import pytest

from sim_hil import firmware as fw
from sim_hil.motor_bus import NO_REPLY, CanMotorBus, DirectMotorBus, open_motor_bus

N = fw.NUM_MOTORS
DT_US = fw.BUS_CYCLE_US


def _frames(k: int) -> bytes:
    q = 0.1 * np.sin(0.05 * k + np.arange(N))
    return fw.pack_commands(q, np.zeros(N), np.full(N, 30.0), np.full(N, 1.0), np.zeros(N))


def _run(bus, ticks: int = 60):
    """Commands every tick but one; a 2-cycle delay at ticks 10–12 (its frames pile onto later cycles:
    late frames); motor 7 off the bus from tick 30. Returns the host's view after each tick."""
    q = np.linspace(-0.2, 0.2, N)
    seen = []
    for k in range(ticks):
        now = k * DT_US
        dead = {7} if k >= 30 else set()
        bus.send_commands(None if k == 5 else _frames(k), now, 0.0, 2 if 10 <= k <= 12 else 0, dead)
        tau = bus.motor_torques(q, np.zeros(N), now, dead)
        q = q + 1e-3 * np.tanh(tau)
        bus.exchange_replies(q, np.zeros(N), tau, now, 0.0, dead)
        seen.append((bus.q.copy(), bus.dq.copy(), bus.tau.copy(), bus.status.copy(), bus.frames_late))
    return seen


def test_direct_and_python_can_buses_agree_tick_for_tick():
    direct, python_can = _run(DirectMotorBus()), _run(CanMotorBus("virtual"))
    assert direct[-1][4] > 0                      # the delay overflowed a cycle: frames were late
    for k, (a, b) in enumerate(zip(direct, python_can)):
        for x, y in zip(a[:4], b[:4]):
            np.testing.assert_array_equal(x, y, err_msg=f"tick {k}")
        assert a[4] == b[4], f"tick {k}: late frames {a[4]} vs {b[4]}"
    assert direct[-1][3][7] & NO_REPLY            # the dead motor never answers


def test_lost_frames_are_lost_at_the_rate_asked():
    bus = DirectMotorBus(np.random.default_rng(3))
    missing = 0
    for k in range(200):
        bus.send_commands(_frames(k), k * DT_US, 0.5)
        bus.exchange_replies(np.zeros(N), np.zeros(N), np.zeros(N), k * DT_US, 0.5)
        missing += int(np.count_nonzero(bus.status & NO_REPLY))
    assert 0.4 < missing / (200 * N) < 0.6
    assert 0.4 < bus.link.counters()["frames_dropped"] / (2 * 200 * N) < 0.6


def test_the_interface_is_chosen_by_name_and_a_can_log_needs_python_can(tmp_path):
    assert isinstance(open_motor_bus(), DirectMotorBus)
    logged = open_motor_bus("direct", str(tmp_path / "bus.asc"))
    assert isinstance(logged, CanMotorBus)
    logged.close()
    with pytest.raises(ValueError, match="unknown --can-interface 'socketcan'"):
        open_motor_bus("socketcan")


def test_a_udp_bus_whose_port_is_held_says_which_and_leaves_nothing_open(netns, monkeypatch):
    """A port held by a socket without SO_REUSEADDR is refused by name (the sim reports it as a usage error)."""
    import socket

    from sim_hil import can_wire
    monkeypatch.setattr(can_wire, "UDP_BASE_PORT", can_wire.UDP_BASE_PORT + 400)   # clear of a running sim's
    held = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    held.bind(("", can_wire.UDP_BASE_PORT + 1))
    try:
        with pytest.raises(OSError, match=f"CAN bus 1: cannot bind UDP port {can_wire.UDP_BASE_PORT + 1}"):
            can_wire.open_pair("udp_multicast", 1)
    finally:
        held.close()
    host, motor = can_wire.open_pair("udp_multicast", 1)     # free again: nothing of the failed try is left
    host.shutdown()
    motor.shutdown()
