"""The T1's four CAN buses as python-can Bus objects, with 23 firmware_like motors on the far side.

Per 2 ms bus cycle the host side (the robot's computer, here the LCM bridge) sends one command frame per
motor; each motor latches it, runs its firmware step at the physics rate, and answers with one reply frame
that the host decodes into the joint state. Frames pass through real python-can buses (in-process `virtual`
by default, `udp_multicast` inside the project namespace so outside python-can tools can log or inject),
and through firmware_like's bus model, which counts the bits of every frame and marks the ones that do not
fit in the cycle as late: a late frame arrives one cycle later instead of silently on time.
"""
from __future__ import annotations

import os
import queue
from collections import deque

import can
import numpy as np
from can.interfaces.virtual import VirtualBus, channels_lock

from sim_hil import firmware as fw

BUS_PERIOD_US = 2000            # one command + reply round per control tick (2 ms)
UDP_GROUP = "239.74.163.2"      # IPv4: the IPv6 default group delivers nothing inside the namespace
UDP_BASE_PORT = 43113           # bus b on port 43113 + b: Linux delivers a group's datagrams to every
                                # socket bound to the port, whatever group it joined, so ports separate buses
NO_REPLY = fw.STATUS_HOST_NO_REPLY   # host-side status bit (t1_motor_protocol.h §7): no reply frame this cycle


class SimVirtualBus(VirtualBus):
    """python-can's `virtual` interface (same channel registry: any `can.Bus(interface="virtual",
    channel=...)` in this process sees the traffic, e.g. for a logger or an injector), without the
    per-receiver deepcopy and blocking queue calls of `VirtualBus.send`: at 23k frames per sim second those
    dominated the simulator's profile. A frame is never mutated after it is sent, so sharing it is safe."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # A lock-free C queue in place of queue.Queue; it still accepts put(msg, block, timeout) from
        # stock VirtualBus senders on the same channel.
        with channels_lock:
            slot = self.channel.index(self.queue)
            self.queue = queue.SimpleQueue()
            self.channel[slot] = self.queue

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check_if_open()
        msg.channel = self.channel_id
        msg.is_rx = True                     # as every receiver sees it
        for bus_queue in self.channel:
            if bus_queue is not self.queue or self.receive_own_messages:
                bus_queue.put_nowait(msg)

    def drain(self) -> list[can.Message]:
        """Everything queued, without BusABC.recv's per-frame filtering and debug logging (no filters are
        set on the simulator's own endpoints)."""
        out = []
        try:
            while True:
                out.append(self.queue.get_nowait())
        except queue.Empty:
            return out

    def _recv_internal(self, timeout: float | None):
        try:
            if not timeout:
                return self.queue.get_nowait(), False
            return self.queue.get(block=True, timeout=timeout), False
        except queue.Empty:
            return None, False


def _open_pair(interface: str, bus_index: int) -> tuple[can.BusABC, can.BusABC]:
    """(host side, motor side) endpoints of one physical bus."""
    if interface == "virtual":
        channel = f"t1_bus{bus_index}_{os.getpid()}_{id(object())}"
        kw = dict(channel=channel, receive_own_messages=False, preserve_timestamps=True)
        return SimVirtualBus(**kw), SimVirtualBus(**kw)
    if interface == "udp_multicast":
        kw = dict(interface="udp_multicast", channel=UDP_GROUP, port=UDP_BASE_PORT + bus_index, hop_limit=0)
        return can.Bus(**kw), can.Bus(**kw)
    raise ValueError(f"unknown --can-interface '{interface}' (virtual | udp_multicast)")


def _drain(end: can.BusABC) -> list[can.Message]:
    if isinstance(end, SimVirtualBus):
        return end.drain()
    out = []
    while (msg := end.recv(0.0)) is not None:
        out.append(msg)
    return out


class MotorBus:
    """Host ⇄ 4 buses ⇄ 23 firmware motors. Call `cycle()` once per tick, `motor_torques()` per substep."""

    def __init__(self, interface: str = "virtual", can_log: str | None = None, rng=None):
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.motors = fw.MotorArray()
        self.bus_models = [fw.BusModel(b) for b in range(len(fw.BUS_NAMES))]
        self.ends = [_open_pair(interface, b) for b in range(len(fw.BUS_NAMES))]
        self.log = can.Logger(can_log) if can_log else None
        n = fw.NUM_MOTORS
        self._cmd_ids = [fw.cmd_can_id(i) for i in range(n)]
        self._reply_id_to_motor = {fw.reply_can_id(i): i for i in range(n)}
        self._cmd_id_to_motor = {fw.cmd_can_id(i): i for i in range(n)}
        self._late: list[deque] = [deque() for _ in self.ends]      # frames carried to the next cycle
        self._delayed: deque = deque()                               # (due_cycle, bus, msg) from faults
        self.cycle_index = 0
        self._rx_frames = bytearray(8 * n)                          # command frames as the motors see them
        self.frames_sent = 0
        self.frames_dropped = 0
        # Host's view of the joints, updated from reply frames (quantised like the real bus).
        self.q = np.zeros(n)
        self.dq = np.zeros(n)
        self.tau = np.zeros(n)
        self.status = np.zeros(n, dtype=np.int32)

    # ---- one bus cycle -------------------------------------------------------------------------------
    def send_commands(self, command_frames: bytes | None, now_us: int, drop_rate: float = 0.0,
                      delay_cycles: int = 0, dead: set[int] = frozenset()) -> None:
        """Host → motors: put 23 command frames on the buses and deliver them to the firmware."""
        for model in self.bus_models:
            model.begin_cycle(now_us)
        self._flush_late()
        if command_frames is not None:
            for i, can_id in enumerate(self._cmd_ids):
                msg = can.Message(arbitration_id=can_id, is_extended_id=False,
                                  data=command_frames[8 * i: 8 * i + 8], timestamp=now_us * 1e-6)
                self._transmit(fw.BUS_OF_MOTOR[i], msg, drop_rate, delay_cycles)
        self._release_delayed()
        self._deliver_to_motors(now_us, dead)

    def _transmit(self, bus: int, msg: can.Message, drop_rate: float, delay_cycles: int) -> None:
        if drop_rate > 0.0 and self.rng.random() < drop_rate:
            self.frames_dropped += 1
            return
        if delay_cycles > 0:
            self._delayed.append((self.cycle_index + delay_cycles, bus, msg))
            return
        self._put_on_wire(bus, msg)

    def _put_on_wire(self, bus: int, msg: can.Message) -> None:
        if not self.bus_models[bus].submit(msg.arbitration_id, bytes(msg.data)):
            self._late[bus].append(msg)        # did not fit in this cycle: goes out first next cycle
            return
        self.ends[bus][0 if msg.arbitration_id in self._cmd_id_to_motor else 1].send(msg)
        self.frames_sent += 1
        if self.log is not None:
            self.log.on_message_received(msg)

    def _release_delayed(self) -> None:
        while self._delayed and self._delayed[0][0] <= self.cycle_index:
            _, bus, msg = self._delayed.popleft()
            self._put_on_wire(bus, msg)

    def _flush_late(self) -> None:
        """Frames that were late last cycle take the head of this cycle."""
        for bus, queue in enumerate(self._late):
            pending = list(queue)
            queue.clear()
            for msg in pending:
                self._put_on_wire(bus, msg)

    def _deliver_to_motors(self, now_us: int, dead: set[int]) -> None:
        """Each motor latches the newest well-formed command frame addressed to it (one batched firmware
        call); odd-length frames go through the per-frame path so the firmware flags them BAD_FRAME."""
        mask = 0
        for _, motor_end in self.ends:
            for msg in _drain(motor_end):
                i = self._cmd_id_to_motor.get(msg.arbitration_id)
                if i is None or i in dead:
                    continue                   # not for a motor, or the motor is off the bus
                if len(msg.data) == fw.CMD_DLC:
                    self._rx_frames[8 * i: 8 * i + 8] = msg.data
                    mask |= 1 << i
                else:
                    self.motors.receive(i, bytes(msg.data), now_us)
        if mask:
            self.motors.receive_all(bytes(self._rx_frames), now_us, mask)

    def motor_torques(self, q: np.ndarray, dq: np.ndarray, now_us: int, dead: set[int]) -> np.ndarray:
        """Firmware step of every motor at the physics rate → joint torques [N·m]."""
        tau = self.motors.step(q, dq, now_us)
        for i in dead:
            tau[i] = 0.0
        return tau

    def exchange_replies(self, q_enc: np.ndarray, dq: np.ndarray, tau: np.ndarray, now_us: int,
                         drop_rate: float = 0.0, dead: set[int] = frozenset()) -> None:
        """Motors → host: reply frames, decoded into the host's quantised joint state."""
        replies = self.motors.replies(q_enc, dq, tau)
        for i in range(fw.NUM_MOTORS):
            if i in dead:
                continue
            msg = can.Message(arbitration_id=fw.reply_can_id(i), is_extended_id=False,
                              data=replies[8 * i: 8 * i + fw.REPLY_DLC], timestamp=now_us * 1e-6)
            self._transmit(fw.BUS_OF_MOTOR[i], msg, drop_rate, 0)
        got = np.zeros(fw.NUM_MOTORS, dtype=bool)
        frames = bytearray(8 * fw.NUM_MOTORS)
        for host_end, _ in self.ends:
            for msg in _drain(host_end):
                i = self._reply_id_to_motor.get(msg.arbitration_id)
                if i is None:
                    continue
                frames[8 * i: 8 * i + len(msg.data)] = msg.data
                got[i] = True
        q, dq_r, tau_r, status = fw.unpack_replies(bytes(frames))
        self.q[got], self.dq[got], self.tau[got] = q[got], dq_r[got], tau_r[got]
        self.status[got] = status[got]
        self.status[~got] |= NO_REPLY
        self.cycle_index += 1

    # ---- health --------------------------------------------------------------------------------------
    @property
    def frames_late(self) -> int:
        return sum(m.frames_late for m in self.bus_models)

    def utilisation(self) -> list[float]:
        return [m.utilisation for m in self.bus_models]

    def close(self) -> None:
        for host_end, motor_end in self.ends:
            host_end.shutdown()
            motor_end.shutdown()
        if self.log is not None:
            self.log.stop()
