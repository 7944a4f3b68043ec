"""Thin ctypes binding of the motor firmware (firmware_like, libt1_firmware.so).

The protocol (ids, packing, ranges, status bits) is documented in
firmware_like/include/t1_motor_protocol.h; every number here is read from the library, not copied.
The library is found in ``$T1_BUILD/firmware_like/`` (``T1_BUILD`` defaults to ``<repo>/build``).

Speed: the simulator calls this 500 times per simulated second, so each batch call copies its inputs
into preallocated float64 buffers and passes raw addresses; no ctypes types are built per call.
Arrays are in joint order (messages/contract.json), length NUM_MOTORS; frame buffers are bytes with one
8-byte slot per motor (a reply uses 7 bytes of its slot, byte 7 is 0).
"""
from __future__ import annotations

import ctypes as C
import os
from pathlib import Path

import numpy as np

_REPO = Path(__file__).resolve().parents[1]
_LIB_NAME = "libt1_firmware.so"


def library_path() -> Path:
    """Where the firmware shared library is expected: $T1_BUILD/firmware_like/libt1_firmware.so."""
    return Path(os.environ.get("T1_BUILD", str(_REPO / "build"))) / "firmware_like" / _LIB_NAME


def _load() -> C.CDLL:
    path = library_path()
    if not path.is_file():
        raise FileNotFoundError(
            f"firmware library {path} is missing: run `make build` "
            f"(or point T1_BUILD at the CMake build folder that holds firmware_like/{_LIB_NAME})")
    return C.CDLL(str(path))


_lib = _load()


class _MotorInfo(C.Structure):  # t1_motor_info_t
    _fields_ = [("name", C.c_char_p), ("motor_class", C.c_int), ("torque_limit_nm", C.c_float),
                ("q_min_rad", C.c_float), ("q_max_rad", C.c_float), ("d_safe_nms", C.c_float),
                ("bus", C.c_uint8)]


class _ClassRange(C.Structure):  # t1_class_range_t
    _fields_ = [("v_max_rads", C.c_float), ("t_max_nm", C.c_float)]


_U32_FIELDS = ("num_motors", "num_buses", "cmd_id_base", "reply_id_base", "cmd_dlc", "reply_dlc",
               "slot_bytes", "bitrate_bps", "cycle_us", "watchdog_us", "status_watchdog",
               "status_over_limit", "status_bad_frame", "status_power_on", "status_damping",
               "status_bad_sensor")


class _Protocol(C.Structure):  # t1_protocol_constants_t
    _fields_ = [(n, C.c_uint32) for n in _U32_FIELDS] + [
        ("q_max_rad", C.c_float), ("kp_max", C.c_float), ("kd_max", C.c_float),
        ("soft_stop_full_torque_rad", C.c_float), ("status_no_reply", C.c_uint32)]


class _Bus(C.Structure):  # t1_bus_t
    _fields_ = [("bus_index", C.c_uint8), ("capacity_bits", C.c_uint32), ("cycle_start_us", C.c_uint64),
                ("bits_this_cycle", C.c_uint32), ("bits_last_cycle", C.c_uint32),
                ("frames_this_cycle", C.c_uint32), ("late_this_cycle", C.c_uint32),
                ("frames_total", C.c_uint64), ("frames_late_total", C.c_uint64)]


_P = _Protocol.in_dll(_lib, "T1_PROTOCOL")
NUM_MOTORS: int = int(_P.num_motors)
NUM_BUSES: int = int(_P.num_buses)
CMD_DLC: int = int(_P.cmd_dlc)
REPLY_DLC: int = int(_P.reply_dlc)
SLOT_BYTES: int = int(_P.slot_bytes)
FRAMES_BYTES: int = NUM_MOTORS * SLOT_BYTES
BUS_BITRATE_BPS: int = int(_P.bitrate_bps)
BUS_CYCLE_US: int = int(_P.cycle_us)
WATCHDOG_US: int = int(_P.watchdog_us)
Q_MAX_RAD: float = float(_P.q_max_rad)
KP_MAX: float = float(_P.kp_max)
KD_MAX: float = float(_P.kd_max)

STATUS_WATCHDOG: int = int(_P.status_watchdog)
STATUS_OVER_LIMIT: int = int(_P.status_over_limit)
STATUS_BAD_FRAME: int = int(_P.status_bad_frame)
STATUS_POWER_ON: int = int(_P.status_power_on)
STATUS_DAMPING: int = int(_P.status_damping)
STATUS_BAD_SENSOR: int = int(_P.status_bad_sensor)
STATUS_NOT_FOLLOWING: int = STATUS_WATCHDOG | STATUS_POWER_ON | STATUS_DAMPING
STATUS_NO_REPLY: int = -1  # unpack_replies: the slot did not decode
# Host bit above the reply byte: no reply frame from the motor this bus cycle (set by sim_hil/motor_bus.py).
STATUS_HOST_NO_REPLY: int = int(_P.status_no_reply)

_MOTORS = (_MotorInfo * NUM_MOTORS).in_dll(_lib, "T1_MOTORS")
_RANGES = (_ClassRange * 6).in_dll(_lib, "T1_CLASS_RANGES")
CLASS_NAMES: tuple[str, ...] = ("head", "arm", "waist", "hip", "knee", "ankle")  # t1_motor_class_t order
MOTOR_NAMES: tuple[str, ...] = tuple(m.name.decode() for m in _MOTORS)
MOTOR_CLASS: tuple[str, ...] = tuple(CLASS_NAMES[m.motor_class] for m in _MOTORS)
BUS_OF_MOTOR: tuple[int, ...] = tuple(int(m.bus) for m in _MOTORS)
BUS_NAMES: tuple[str, ...] = tuple(s.decode() for s in (C.c_char_p * NUM_BUSES).in_dll(_lib, "T1_BUS_NAMES"))
TORQUE_LIMIT = np.array([m.torque_limit_nm for m in _MOTORS], dtype=np.float64)  # [N·m], per joint
Q_MIN = np.array([m.q_min_rad for m in _MOTORS], dtype=np.float64)  # soft stops [rad]
Q_MAX = np.array([m.q_max_rad for m in _MOTORS], dtype=np.float64)
D_SAFE = np.array([m.d_safe_nms for m in _MOTORS], dtype=np.float64)  # damping gain [N·m·s/rad]
V_RANGE = np.array([_RANGES[m.motor_class].v_max_rads for m in _MOTORS], dtype=np.float64)  # ± [rad/s]
T_RANGE = np.array([_RANGES[m.motor_class].t_max_nm for m in _MOTORS], dtype=np.float64)  # ± [N·m]
for _a in (TORQUE_LIMIT, Q_MIN, Q_MAX, D_SAFE, V_RANGE, T_RANGE):
    _a.flags.writeable = False
ALL_MOTORS_MASK: int = (1 << NUM_MOTORS) - 1

# ---- C signatures (pointers as c_void_p: a Python int address passes without conversion cost) ----
_vp, _u32, _u64, _u8 = C.c_void_p, C.c_uint32, C.c_uint64, C.c_uint8


def _sig(name: str, restype, *argtypes):
    fn = getattr(_lib, name)
    fn.restype, fn.argtypes = restype, list(argtypes)
    return fn


_motor_array_size = _sig("t1_motor_array_size", C.c_size_t)
_bus_array_size = _sig("t1_bus_array_size", C.c_size_t)
_motor_array_init = _sig("t1_motor_array_init", None, _vp)
_bus_init = _sig("t1_bus_init", C.c_int, _vp, C.c_uint, _u32, _u32)
_bus_begin_cycle = _sig("t1_bus_begin_cycle", None, _vp, _u64)
_bus_submit = _sig("t1_bus_submit", C.c_int, _vp, _u32, C.c_char_p, _u8)
_frame_bits = _sig("t1_can_frame_bits", _u32, _u32, C.c_char_p, _u8)
_error_name = _sig("t1_error_name", C.c_char_p, C.c_int)
_motor_receive = _sig("t1_motor_receive", C.c_int, _vp, _u32, C.c_char_p, _u8, _u64)
_pack_all = _sig("t1_batch_pack_commands", _u32, _vp, _vp, _vp, _vp, _vp, _vp)
_receive_all = _sig("t1_batch_receive", _u32, _vp, C.c_char_p, _u32, _u64)
_step_all = _sig("t1_batch_step", None, _vp, _vp, _vp, _u64, _vp)
_replies_all = _sig("t1_batch_replies", None, _vp, _vp, _vp, _vp, _vp)
_unpack_replies_all = _sig("t1_batch_unpack_replies", _u32, C.c_char_p, _vp, _vp, _vp, _vp)
_unpack_commands_all = _sig("t1_batch_unpack_commands", None, C.c_char_p, _vp, _vp, _vp, _vp, _vp)
_status_all = _sig("t1_batch_status", None, _vp, _vp)
_bus_cycle_all = _sig("t1_batch_bus_cycle", None, _vp, _u64, C.c_char_p, _u32, C.c_char_p, _vp, _vp)

if C.sizeof(_Bus) * NUM_BUSES != _bus_array_size():
    raise ImportError("sim_hil.firmware: t1_bus_t layout differs from the library; rebuild (make build)")


def _check_index(i: int) -> int:
    if not 0 <= i < NUM_MOTORS:
        raise IndexError(f"motor index {i} outside 0..{NUM_MOTORS - 1}")
    return int(i)


def cmd_can_id(i: int) -> int:
    """CAN id of motor i's command frame (0x100 + motor id, motor id = i + 1)."""
    return int(_P.cmd_id_base) + _check_index(i) + 1


def reply_can_id(i: int) -> int:
    """CAN id of motor i's reply frame (0x200 + motor id)."""
    return int(_P.reply_id_base) + _check_index(i) + 1


def error_name(code: int) -> str:
    return _error_name(code).decode()


def can_frame_bits(can_id: int, data: bytes) -> int:
    """Exact bits on the wire of a CAN 2.0A data frame (stuffing, CRC, ACK, EOF, IFS included)."""
    data = bytes(data)
    if len(data) > 8 or not 0 <= can_id <= 0x7FF:
        raise ValueError(f"not a CAN 2.0A data frame: id {can_id:#x}, {len(data)} bytes")
    return int(_frame_bits(can_id, data, len(data)))


class _Vec:
    """A preallocated float64[NUM_MOTORS] input buffer with its address (inputs are copied into it)."""
    __slots__ = ("a", "p")

    def __init__(self) -> None:
        self.a = np.zeros(NUM_MOTORS, dtype=np.float64)
        self.p = self.a.ctypes.data

    def load(self, x, what: str) -> int:
        try:
            self.a[:] = x
        except ValueError as e:
            raise ValueError(f"{what}: expected {NUM_MOTORS} values in joint order ({e})") from None
        return self.p


def _frames(data, what: str) -> bytes:
    if not isinstance(data, bytes):
        data = bytes(data)
    if len(data) != FRAMES_BYTES:
        raise ValueError(f"{what}: expected {FRAMES_BYTES} bytes ({NUM_MOTORS} slots of {SLOT_BYTES}), "
                         f"got {len(data)}")
    return data


_pk = [_Vec() for _ in range(5)]
_pack_out = np.zeros(FRAMES_BYTES, dtype=np.uint8)
_pack_out_p = _pack_out.ctypes.data
_PACK_FIELDS = ("q_des", "dq_des", "kp", "kd", "tau_ff")


def pack_commands_masked(q_des, dq_des, kp, kd, tau_ff) -> tuple[bytes, np.ndarray]:
    """Pack all 23 commands. Returns (frames, ok): ok[i] is False where a field was non-finite (that
    slot is zeroed and must not be sent). Values beyond a range saturate at the edge."""
    args = [v.load(x, n) for v, x, n in zip(_pk, (q_des, dq_des, kp, kd, tau_ff), _PACK_FIELDS)]
    bad = _pack_all(*args, _pack_out_p)
    ok = np.array([not (bad >> i) & 1 for i in range(NUM_MOTORS)]) if bad else np.ones(NUM_MOTORS, bool)
    return _pack_out.tobytes(), ok


def pack_commands(q_des, dq_des, kp, kd, tau_ff) -> bytes:
    """Pack all 23 commands into NUM_MOTORS × 8 bytes; a non-finite value raises ValueError naming it."""
    args = [v.load(x, n) for v, x, n in zip(_pk, (q_des, dq_des, kp, kd, tau_ff), _PACK_FIELDS)]
    if _pack_all(*args, _pack_out_p):
        bad = [f"{n}[{i}] ({MOTOR_NAMES[i]}) = {v.a[i]}" for v, n in zip(_pk, _PACK_FIELDS)
               for i in range(NUM_MOTORS) if not np.isfinite(v.a[i])]
        raise ValueError("non-finite command value(s), not packed: " + ", ".join(bad))
    return _pack_out.tobytes()


def unpack_command(data: bytes, motor_index: int | None = None):
    """Decode command frames. 8 bytes + motor_index → (q_des, dq_des, kp, kd, tau_ff) floats;
    NUM_MOTORS × 8 bytes → the same five as float64[23] arrays."""
    data = bytes(data)
    if len(data) == FRAMES_BYTES and motor_index is None:
        out = [np.empty(NUM_MOTORS) for _ in range(5)]
        _unpack_commands_all(data, *(o.ctypes.data for o in out))
        return tuple(out)
    if len(data) != CMD_DLC or motor_index is None:
        raise ValueError(f"unpack_command: give {CMD_DLC} bytes and a motor_index, or {FRAMES_BYTES} "
                         f"bytes (all motors); got {len(data)} bytes, motor_index={motor_index}")
    i = _check_index(motor_index)
    slots = bytes(i * SLOT_BYTES) + data + bytes(FRAMES_BYTES - (i + 1) * SLOT_BYTES)
    return tuple(float(a[i]) for a in unpack_command(slots))


_uq, _udq, _utau = (np.empty(NUM_MOTORS) for _ in range(3))
_ust = np.empty(NUM_MOTORS, dtype=np.int32)
_u_ptrs = (_uq.ctypes.data, _udq.ctypes.data, _utau.ctypes.data, _ust.ctypes.data)


def unpack_replies(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Decode NUM_MOTORS reply slots → (q [rad], dq [rad/s], tau [N·m], status int32). A slot that does
    not hold motor i's reply gives NaN and status STATUS_NO_REPLY (-1)."""
    _unpack_replies_all(_frames(data, "unpack_replies"), *_u_ptrs)
    return _uq.copy(), _udq.copy(), _utau.copy(), _ust.copy()


class MotorArray:
    """The 23 motors' firmware state (power-on: damping). Times are integer microseconds."""

    def __init__(self) -> None:
        words = -(-_motor_array_size() // 8)
        self._state = np.zeros(words, dtype=np.uint64)  # 8-byte aligned backing store of t1_motor_array_t
        self._p = self._state.ctypes.data
        self._motor_size = _motor_array_size() // NUM_MOTORS
        self._q, self._dq, self._tau = _Vec(), _Vec(), _Vec()
        self._tau_out = np.zeros(NUM_MOTORS)
        self._tau_out_p = self._tau_out.ctypes.data
        self._frames = np.zeros(FRAMES_BYTES, dtype=np.uint8)
        self._frames_p = self._frames.ctypes.data
        self._status = np.zeros(NUM_MOTORS, dtype=np.int32)
        self._status_p = self._status.ctypes.data
        self.reset()

    @property
    def address(self) -> int:
        """Address of the t1_motor_array_t (for the simulator's C++ tick)."""
        return self._p

    def reset(self) -> None:
        """Power-on reset of every motor (call on a simulator reset: time may restart from 0)."""
        _motor_array_init(self._p)

    def receive(self, i: int, data: bytes, now_us: int, can_id: int | None = None) -> bool:
        """Deliver one command frame to motor i (can_id defaults to its own command id). Returns True
        if accepted; a malformed frame sets BAD_FRAME in the motor's status and returns False."""
        i = _check_index(i)
        data = bytes(data)
        cid = cmd_can_id(i) if can_id is None else int(can_id)
        rc = _motor_receive(self._p + i * self._motor_size, cid, data, len(data) if len(data) < 256 else 255,
                            int(now_us))
        return rc == 0

    def receive_all(self, frames: bytes, now_us: int, deliver_mask: int = ALL_MOTORS_MASK) -> int:
        """Deliver slot i to motor i for each bit i of deliver_mask; returns the mask of rejected frames."""
        return int(_receive_all(self._p, _frames(frames, "receive_all"), deliver_mask & ALL_MOTORS_MASK,
                                int(now_us)))

    def step(self, q, dq, now_us: int) -> np.ndarray:
        """One firmware step of all motors: torque [N·m] per joint (clamped, watchdog, soft stops)."""
        _step_all(self._p, self._q.load(q, "q"), self._dq.load(dq, "dq"), int(now_us), self._tau_out_p)
        return self._tau_out.copy()

    def replies(self, q, dq, tau) -> bytes:
        """All 23 reply frames (7 bytes each in an 8-byte slot) from measured q, dq and applied tau."""
        _replies_all(self._p, self._q.load(q, "q"), self._dq.load(dq, "dq"), self._tau.load(tau, "tau"),
                     self._frames_p)
        return self._frames.tobytes()

    @property
    def status(self) -> np.ndarray:
        """Status bits of every motor after the last receive/step (int32[23])."""
        _status_all(self._p, self._status_p)
        return self._status.copy()


class BusModel:
    """One CAN bus (1 Mbit/s, 2 ms cycle): counts exact frame bits per cycle, flags late frames."""

    def __init__(self, bus_index: int) -> None:
        if not 0 <= bus_index < NUM_BUSES:
            raise IndexError(f"bus index {bus_index} outside 0..{NUM_BUSES - 1} ({', '.join(BUS_NAMES)})")
        self._bus = _Bus()
        self._p = C.addressof(self._bus)
        _bus_init(self._p, bus_index, BUS_BITRATE_BPS, BUS_CYCLE_US)
        self.bus_index, self.name = bus_index, BUS_NAMES[bus_index]

    def begin_cycle(self, now_us: int) -> None:
        _bus_begin_cycle(self._p, int(now_us))

    def submit(self, can_id: int, data: bytes) -> bool:
        """Queue a frame in the running cycle: True if it ends within the cycle, False if LATE."""
        data = bytes(data)
        rc = _bus_submit(self._p, int(can_id), data, min(len(data), 255))
        if rc < 0:
            raise ValueError(f"bus {self.name}: not a CAN 2.0A data frame (id {can_id:#x}, "
                             f"{len(data)} bytes): {error_name(rc)}")
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
        self._buses = (_Bus * NUM_BUSES)()
        self._p = C.addressof(self._buses)
        for k in range(NUM_BUSES):
            _bus_init(self._p + k * C.sizeof(_Bus), k, BUS_BITRATE_BPS, BUS_CYCLE_US)
        self._cmd_ok = np.zeros(NUM_MOTORS, dtype=np.uint8)
        self._rep_ok = np.zeros(NUM_MOTORS, dtype=np.uint8)
        self._cmd_ok_p, self._rep_ok_p = self._cmd_ok.ctypes.data, self._rep_ok.ctypes.data

    def cycle(self, now_us: int, commands: bytes, replies: bytes, cmd_mask: int = ALL_MOTORS_MASK
              ) -> tuple[np.ndarray, np.ndarray]:
        """Run one bus cycle; returns (command on time, reply on time) as bool[23]. Only motors in
        cmd_mask send a command; every motor replies."""
        _bus_cycle_all(self._p, int(now_us), _frames(commands, "commands"), cmd_mask & ALL_MOTORS_MASK,
                       _frames(replies, "replies"), self._cmd_ok_p, self._rep_ok_p)
        return self._cmd_ok.astype(bool), self._rep_ok.astype(bool)

    @property
    def utilisation(self) -> np.ndarray:
        """Per bus: bits of the cycle just run / capacity."""
        return np.array([b.bits_this_cycle / b.capacity_bits for b in self._buses])

    @property
    def frames_late(self) -> np.ndarray:
        """Per bus: late frames since construction."""
        return np.array([b.frames_late_total for b in self._buses], dtype=np.int64)


_link_size = _sig("t1_link_size", C.c_size_t)
_link_init = _sig("t1_link_init", C.c_int, _vp)
_link_send = _sig("t1_link_send_commands", _u32, _vp, _vp, _u64, C.c_char_p, _u32, _u32, _u32, _u32)
_link_counters = _sig("t1_link_counters", None, _vp, _vp)
_host_view_update = _sig("t1_host_view_update", None, C.c_char_p, _u32, _vp, _vp, _vp, _vp)
_link_replies = _sig("t1_link_exchange_replies", _u32, _vp, C.c_char_p, _u32, _u32, _vp)


class HostView:
    """The host's view of the joints from the reply frames (quantised like the real bus): q [rad],
    dq [rad/s], tau [N·m], status bits, in joint order, updated in place once per bus cycle."""

    def __init__(self) -> None:
        self.q, self.dq, self.tau = (np.zeros(NUM_MOTORS) for _ in range(3))
        self.status = np.zeros(NUM_MOTORS, dtype=np.int32)
        self._ptrs = tuple(a.ctypes.data for a in (self.q, self.dq, self.tau, self.status))

    def update(self, frames: bytes, got_mask: int) -> None:
        """Motors in got_mask take their reply slot's values; the others keep theirs, gaining
        STATUS_HOST_NO_REPLY (t1_host_view_update)."""
        _host_view_update(_frames(frames, "HostView.update"), got_mask & ALL_MOTORS_MASK, *self._ptrs)


class Link:
    """The 4 buses between host and motors in two calls per tick (t1_firmware.h, "host link"): late frames
    carried to the next cycle, delayed and lost frames, dead motors, every frame counted by its bus model."""

    def __init__(self) -> None:
        self._state = np.zeros(-(-_link_size() // 8), dtype=np.uint64)   # 8-byte aligned t1_link_t
        self._p = self._state.ctypes.data
        _link_init(self._p)
        self.buses = (_Bus * NUM_BUSES).from_address(self._p)             # the struct's first member
        self.host_frames = np.zeros(FRAMES_BYTES, dtype=np.uint8)
        self._host_p = self.host_frames.ctypes.data

    def send_commands(self, motors: MotorArray, now_us: int, frames: bytes | None, drop_mask: int = 0,
                      delay_cycles: int = 0, dead_mask: int = 0) -> int:
        """Host → motors; returns the mask of motors that latched a command this cycle."""
        send = ALL_MOTORS_MASK if frames is not None else 0
        return int(_link_send(self._p, motors._p, now_us, frames, send, drop_mask, delay_cycles, dead_mask))

    @property
    def address(self) -> int:
        """Address of the t1_link_t (for the simulator's C++ tick)."""
        return self._p

    def counters(self) -> dict[str, int]:
        """Frames put on time on a wire, lost on it, and lost to a full carry or delay queue."""
        out = np.zeros(3, dtype=np.uint64)
        _link_counters(self._p, out.ctypes.data)
        return dict(zip(("frames_sent", "frames_dropped", "frames_lost_overflow"), map(int, out)))

    def exchange_replies(self, replies: bytes, send_mask: int = ALL_MOTORS_MASK, drop_mask: int = 0) -> int:
        """Motors → host, closing the cycle; the received replies are in host_frames, their mask returned."""
        return int(_link_replies(self._p, replies, send_mask, drop_mask, self._host_p))
