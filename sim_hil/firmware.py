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


def bind(name: str, restype, *argtypes):
    """The library function `name` with its C signature set (pointers as c_void_p)."""
    fn = getattr(_lib, name)
    fn.restype, fn.argtypes = restype, list(argtypes)
    return fn


_motor_array_size = bind("t1_motor_array_size", C.c_size_t)
_motor_array_init = bind("t1_motor_array_init", None, _vp)
_frame_bits = bind("t1_can_frame_bits", _u32, _u32, C.c_char_p, _u8)
_error_name = bind("t1_error_name", C.c_char_p, C.c_int)
_motor_receive = bind("t1_motor_receive", C.c_int, _vp, _u32, C.c_char_p, _u8, _u64)
_pack_all = bind("t1_batch_pack_commands", _u32, _vp, _vp, _vp, _vp, _vp, _vp)
_receive_all = bind("t1_batch_receive", _u32, _vp, C.c_char_p, _u32, _u64)
_step_all = bind("t1_batch_step", None, _vp, _vp, _vp, _u64, _vp)
_replies_all = bind("t1_batch_replies", None, _vp, _vp, _vp, _vp, _vp)
_unpack_replies_all = bind("t1_batch_unpack_replies", _u32, C.c_char_p, _vp, _vp, _vp, _vp)
_unpack_commands_all = bind("t1_batch_unpack_commands", None, C.c_char_p, _vp, _vp, _vp, _vp, _vp)
_status_all = bind("t1_batch_status", None, _vp, _vp)



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


def check_frames(data, what: str) -> bytes:
    """data as bytes of NUM_MOTORS frame slots, or ValueError naming `what`."""
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
    _unpack_replies_all(check_frames(data, "unpack_replies"), *_u_ptrs)
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
        return int(_receive_all(self._p, check_frames(frames, "receive_all"), deliver_mask & ALL_MOTORS_MASK,
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
