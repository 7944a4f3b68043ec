"""ctypes binding of firmware_like's bus side (libt1_firmware.so through sim_hil/firmware.py): the CAN bus
model, the four buses in one call, the host link (t1_link.c) and the host's joint view decoded from the
reply frames."""
from __future__ import annotations

import ctypes as C

import numpy as np

from sim_hil import firmware as fw
from sim_hil.firmware import MotorArray

_vp, _u32, _u64, _u8 = C.c_void_p, C.c_uint32, C.c_uint64, C.c_uint8


class _Bus(C.Structure):  # t1_bus_t
    _fields_ = [("bus_index", C.c_uint8), ("capacity_bits", C.c_uint32), ("cycle_start_us", C.c_uint64),
                ("bits_this_cycle", C.c_uint32), ("bits_last_cycle", C.c_uint32),
                ("frames_this_cycle", C.c_uint32), ("late_this_cycle", C.c_uint32),
                ("frames_total", C.c_uint64), ("frames_late_total", C.c_uint64)]


_bus_array_size = fw.bind("t1_bus_array_size", C.c_size_t)
_bus_init = fw.bind("t1_bus_init", C.c_int, _vp, C.c_uint, _u32, _u32)
_bus_begin_cycle = fw.bind("t1_bus_begin_cycle", None, _vp, _u64)
_bus_submit = fw.bind("t1_bus_submit", C.c_int, _vp, _u32, C.c_char_p, _u8)
_bus_cycle_all = fw.bind("t1_batch_bus_cycle", None, _vp, _u64, C.c_char_p, _u32, C.c_char_p, _vp, _vp)

if C.sizeof(_Bus) * fw.NUM_BUSES != _bus_array_size():
    raise ImportError("sim_hil.firmware_buses: t1_bus_t layout differs from the library; rebuild (make build)")


class BusModel:
    """One CAN bus (1 Mbit/s, 2 ms cycle): counts exact frame bits per cycle, flags late frames."""

    def __init__(self, bus_index: int) -> None:
        if not 0 <= bus_index < fw.NUM_BUSES:
            raise IndexError(f"bus index {bus_index} outside 0..{fw.NUM_BUSES - 1} ({', '.join(fw.BUS_NAMES)})")
        self._bus = _Bus()
        self._p = C.addressof(self._bus)
        _bus_init(self._p, bus_index, fw.BUS_BITRATE_BPS, fw.BUS_CYCLE_US)
        self.bus_index, self.name = bus_index, fw.BUS_NAMES[bus_index]

    def begin_cycle(self, now_us: int) -> None:
        _bus_begin_cycle(self._p, int(now_us))

    def submit(self, can_id: int, data: bytes) -> bool:
        """Queue a frame in the running cycle: True if it ends within the cycle, False if LATE."""
        data = bytes(data)
        rc = _bus_submit(self._p, int(can_id), data, min(len(data), 255))
        if rc < 0:
            raise ValueError(f"bus {self.name}: not a CAN 2.0A data frame (id {can_id:#x}, "
                             f"{len(data)} bytes): {fw.error_name(rc)}")
        return rc == 1

    @property
    def utilisation(self) -> float:
        """Offered bits of the last completed cycle / capacity (> 1 = overload)."""
        return self._bus.bits_last_cycle / self._bus.capacity_bits

    @property
    def bits_this_cycle(self) -> int:
        return int(self._bus.bits_this_cycle)

    @property
    def capacity_bits(self) -> int:
        return int(self._bus.capacity_bits)

    @property
    def frames_late(self) -> int:
        return int(self._bus.frames_late_total)

    @property
    def frames_total(self) -> int:
        return int(self._bus.frames_total)


class BusArray:
    """All 4 buses in one call per tick: every command (id order), then every reply, per cycle."""

    def __init__(self) -> None:
        self._buses = (_Bus * fw.NUM_BUSES)()
        self._p = C.addressof(self._buses)
        for k in range(fw.NUM_BUSES):
            _bus_init(self._p + k * C.sizeof(_Bus), k, fw.BUS_BITRATE_BPS, fw.BUS_CYCLE_US)
        self._cmd_ok = np.zeros(fw.NUM_MOTORS, dtype=np.uint8)
        self._rep_ok = np.zeros(fw.NUM_MOTORS, dtype=np.uint8)
        self._cmd_ok_p, self._rep_ok_p = self._cmd_ok.ctypes.data, self._rep_ok.ctypes.data

    def cycle(self, now_us: int, commands: bytes, replies: bytes, cmd_mask: int = fw.ALL_MOTORS_MASK
              ) -> tuple[np.ndarray, np.ndarray]:
        """Run one bus cycle; returns (command on time, reply on time) as bool[23]. Only motors in
        cmd_mask send a command; every motor replies."""
        _bus_cycle_all(self._p, int(now_us), fw.check_frames(commands, "commands"), cmd_mask & fw.ALL_MOTORS_MASK,
                       fw.check_frames(replies, "replies"), self._cmd_ok_p, self._rep_ok_p)
        return self._cmd_ok.astype(bool), self._rep_ok.astype(bool)

    @property
    def utilisation(self) -> np.ndarray:
        """Per bus: bits of the cycle just run / capacity."""
        return np.array([b.bits_this_cycle / b.capacity_bits for b in self._buses])

    @property
    def frames_late(self) -> np.ndarray:
        """Per bus: late frames since construction."""
        return np.array([b.frames_late_total for b in self._buses], dtype=np.int64)


_link_size = fw.bind("t1_link_size", C.c_size_t)
_link_init = fw.bind("t1_link_init", C.c_int, _vp)
_link_send = fw.bind("t1_link_send_commands", _u32, _vp, _vp, _u64, C.c_char_p, _u32, _u32, _u32, _u32)
_link_counters = fw.bind("t1_link_counters", None, _vp, _vp)
_host_view_update = fw.bind("t1_host_view_update", None, C.c_char_p, _u32, _vp, _vp, _vp, _vp)
_link_replies = fw.bind("t1_link_exchange_replies", _u32, _vp, C.c_char_p, _u32, _u32, _vp)


class HostView:
    """The host's view of the joints from the reply frames (quantised like the real bus): q [rad],
    dq [rad/s], tau [N·m], status bits, in joint order, updated in place once per bus cycle."""

    def __init__(self) -> None:
        self.q, self.dq, self.tau = (np.zeros(fw.NUM_MOTORS) for _ in range(3))
        self.status = np.zeros(fw.NUM_MOTORS, dtype=np.int32)
        self._ptrs = tuple(a.ctypes.data for a in (self.q, self.dq, self.tau, self.status))

    def update(self, frames: bytes, got_mask: int) -> None:
        """Motors in got_mask take their reply slot's values; the others keep theirs, gaining
        STATUS_HOST_NO_REPLY (t1_host_view_update)."""
        _host_view_update(fw.check_frames(frames, "HostView.update"), got_mask & fw.ALL_MOTORS_MASK, *self._ptrs)


class Link:
    """The 4 buses between host and motors in two calls per tick (t1_firmware.h, "host link"): late frames
    carried to the next cycle, delayed and lost frames, dead motors, every frame counted by its bus model."""

    def __init__(self) -> None:
        self._state = np.zeros(-(-_link_size() // 8), dtype=np.uint64)   # 8-byte aligned t1_link_t
        self._p = self._state.ctypes.data
        _link_init(self._p)
        self.buses = (_Bus * fw.NUM_BUSES).from_address(self._p)             # the struct's first member
        self.host_frames = np.zeros(fw.FRAMES_BYTES, dtype=np.uint8)
        self._host_p = self.host_frames.ctypes.data

    def send_commands(self, motors: MotorArray, now_us: int, frames: bytes | None, drop_mask: int = 0,
                      delay_cycles: int = 0, dead_mask: int = 0) -> int:
        """Host → motors; returns the mask of motors that latched a command this cycle."""
        send = fw.ALL_MOTORS_MASK if frames is not None else 0
        return int(_link_send(self._p, motors.address, now_us, frames, send, drop_mask, delay_cycles, dead_mask))

    @property
    def address(self) -> int:
        """Address of the t1_link_t (for the simulator's C++ tick)."""
        return self._p

    def counters(self) -> dict[str, int]:
        """Frames put on time on a wire, lost on it, and lost to a full carry or delay queue."""
        out = np.zeros(3, dtype=np.uint64)
        _link_counters(self._p, out.ctypes.data)
        return dict(zip(("frames_sent", "frames_dropped", "frames_lost_overflow"), map(int, out)))

    def exchange_replies(self, replies: bytes, send_mask: int = fw.ALL_MOTORS_MASK, drop_mask: int = 0) -> int:
        """Motors → host, closing the cycle; the received replies are in host_frames, their mask returned."""
        return int(_link_replies(self._p, replies, send_mask, drop_mask, self._host_p))
