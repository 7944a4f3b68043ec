"""The T1's four CAN buses with 23 firmware_like motors on the far side.

Per 2 ms bus cycle the host side (the robot's computer, here the LCM bridge) sends one command frame per
motor; each motor latches it, runs its firmware step at the physics rate, and answers with one reply frame
that the host decodes into the joint state. firmware_like's bus model counts the bits of every frame and
marks the ones that do not fit in the cycle as late: a late frame arrives one cycle later instead of
silently on time. Two carriers of the same frames:

* `direct` (default): firmware_like's host link in C (t1_link.c), two calls per tick, the frames never
  become Python objects: what lets the simulator run many times faster than real time in lockstep;
* `virtual` / `udp_multicast`: real python-can buses (`virtual` in-process, `udp_multicast` inside the
  project namespace, so outside python-can tools can log or inject), frame by frame; `--can-log` uses them.
"""
from __future__ import annotations

from collections import deque
from pathlib import Path

import can
import numpy as np

from sim_hil import can_wire
from sim_hil import firmware as fw
from sim_hil import firmware_buses as fwb

INTERFACES = ("direct", "virtual", "udp_multicast")
NO_REPLY = fw.STATUS_HOST_NO_REPLY   # host-side status bit (t1_motor_protocol.h §7): no reply frame this cycle


def open_motor_bus(interface: str = "direct", can_log: str | None = None, rng=None) -> "MotorBus":
    """The buses for --can-interface / --can-log: a CAN log needs python-can frames (in-process `virtual`
    where the interface was left at `direct`)."""
    if interface not in INTERFACES:
        raise ValueError(f"unknown --can-interface '{interface}' ({' | '.join(INTERFACES)})")
    if interface == "direct" and not can_log:
        return DirectMotorBus(rng)
    return CanMotorBus("virtual" if interface == "direct" else interface, can_log, rng)


def mask(indices) -> int:
    """Motor indices → a bit mask (bit i = motor i)."""
    return sum(1 << i for i in indices)


class MotorBus:
    """Host ⇄ 4 buses ⇄ 23 firmware motors. Per tick: `send_commands()`, `motor_torques()` per physics
    substep, `exchange_replies()`; the host's view of the joints is q, dq, tau, status."""

    def __init__(self, rng=None):
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.motors = fw.MotorArray()
        self.view = fwb.HostView()
        self.q, self.dq, self.tau, self.status = self.view.q, self.view.dq, self.view.tau, self.view.status

    def motor_torques(self, q: np.ndarray, dq: np.ndarray, now_us: int, dead: set[int]) -> np.ndarray:
        """Firmware step of every motor at the physics rate → joint torques [N·m]."""
        tau = self.motors.step(q, dq, now_us)
        for i in dead:
            tau[i] = 0.0
        return tau

    def _host_receives(self, frames: bytes, got_mask: int) -> None:
        """Decode the replies the host got this cycle; a motor without one keeps its last values, flagged."""
        self.view.update(frames, got_mask)


class DirectMotorBus(MotorBus):
    """The buses as firmware_like's host link: the same frames, bus model, late, lost and delayed frames
    and dead motors as CanMotorBus, in C."""

    _BITS = 1 << np.arange(fw.NUM_MOTORS)

    def __init__(self, rng=None):
        super().__init__(rng)
        self.link = fwb.Link()

    def lost_mask(self, drop_rate: float) -> int:
        """Which of the 23 frames of one direction the wire loses this cycle, each with drop_rate."""
        if drop_rate <= 0.0:
            return 0
        return int(self._BITS[self.rng.random(fw.NUM_MOTORS) < drop_rate].sum())

    def send_commands(self, command_frames: bytes | None, now_us: int, drop_rate: float = 0.0,
                      delay_cycles: int = 0, dead: set[int] = frozenset()) -> None:
        self.link.send_commands(self.motors, now_us, command_frames, self.lost_mask(drop_rate), delay_cycles,
                                mask(dead))

    def exchange_replies(self, q_enc: np.ndarray, dq: np.ndarray, tau: np.ndarray, now_us: int,
                         drop_rate: float = 0.0, dead: set[int] = frozenset()) -> None:
        replies = self.motors.replies(q_enc, dq, tau)
        got = self.link.exchange_replies(replies, fw.ALL_MOTORS_MASK & ~mask(dead), self.lost_mask(drop_rate))
        self._host_receives(self.link.host_frames.tobytes(), got)

    @property
    def frames_late(self) -> int:
        return sum(b.frames_late_total for b in self.link.buses)

    def utilisation(self) -> list[float]:
        return [b.bits_last_cycle / b.capacity_bits for b in self.link.buses]

    def close(self) -> None:
        pass


class CanMotorBus(MotorBus):
    """The buses as python-can endpoints, frame by frame (--can-interface virtual | udp_multicast, --can-log)."""

    def __init__(self, interface: str = "virtual", can_log: str | None = None, rng=None):
        super().__init__(rng)
        self.bus_models = [fwb.BusModel(b) for b in range(len(fw.BUS_NAMES))]
        self.ends = [can_wire.open_pair(interface, b) for b in range(len(fw.BUS_NAMES))]
        if can_log:
            Path(can_log).parent.mkdir(parents=True, exist_ok=True)   # like --record's and --log's folders
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
            for msg in can_wire.drain(motor_end):
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
        got = 0
        frames = bytearray(8 * fw.NUM_MOTORS)
        for host_end, _ in self.ends:
            for msg in can_wire.drain(host_end):
                i = self._reply_id_to_motor.get(msg.arbitration_id)
                if i is None:
                    continue
                frames[8 * i: 8 * i + len(msg.data)] = msg.data
                got |= 1 << i
        self._host_receives(bytes(frames), got)
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
