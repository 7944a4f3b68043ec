"""ctypes binding of the simulator's C++ core (sim_hil/core, libt1_sim_core.so): the LCM robot link
(`Link`, behind sim_hil/lcm_bridge.py) and the lockstep tick in one call (`LockstepTick`, used by
sim_hil/sim.py whenever a tick needs nothing that lives in Python). Found in $T1_BUILD/sim_hil/core/."""
from __future__ import annotations

import ctypes as C
import os
from pathlib import Path

import mujoco
import numpy as np

from sim_hil import firmware as fw

_REPO = Path(__file__).resolve().parents[1]
_LIB_NAME = "libt1_sim_core.so"
MAX_COMMAND_BYTES = 4096      # a T1_JOINT_CMD payload is ~500 bytes


def library_path() -> Path:
    return Path(os.environ.get("T1_BUILD", str(_REPO / "build"))) / "sim_hil" / "core" / _LIB_NAME


def _load() -> C.CDLL:
    path = library_path()
    if not path.is_file():
        raise FileNotFoundError(f"simulator core {path} is missing: run `make build` (or point T1_BUILD at "
                                "the CMake build folder)")
    lib = C.CDLL(str(path))
    vp, i64, f64 = C.c_void_p, C.c_int64, C.c_double
    for name, res, args in (
            ("t1_sim_link_open", vp, [C.c_char_p]), ("t1_sim_link_close", None, [vp]),
            ("t1_sim_link_set_robot_key", C.c_int, [vp, i64, C.c_char_p, C.c_int]),
            ("t1_sim_link_publish", C.c_int, [vp, C.c_char_p, C.c_char_p, C.c_int]),
            ("t1_sim_link_publish_state", None, [vp, i64, i64] + [vp] * 7),
            ("t1_sim_link_poll", None, [vp, f64]), ("t1_sim_link_wait_for_answer", C.c_int, [vp, i64, f64]),
            ("t1_sim_link_take_frames", C.c_int, [vp, vp]), ("t1_sim_link_latest", C.c_int, [vp, vp, C.c_int]),
            ("t1_sim_link_counters", None, [vp, vp]), ("t1_sim_link_last_drop_reason", C.c_char_p, [vp]),
            ("t1_sim_lockstep_tick", C.c_int, [vp, vp, vp, i64, f64]),
            ("t1_sim_lockstep_ticks", C.c_int, [vp, vp, vp, i64, C.c_int, f64])):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    return lib


_lib = _load()


class Link:
    """The LCM robot link: state out, commands in (validated, packed into CAN command frames)."""

    def __init__(self, url: str):
        self._p = _lib.t1_sim_link_open(url.encode())
        if not self._p:
            raise RuntimeError(f"cannot open LCM at '{url}' (run inside tools/netns)")
        self._frames = np.zeros(fw.FRAMES_BYTES, dtype=np.uint8)
        self._payload = np.zeros(MAX_COMMAND_BYTES, dtype=np.uint8)
        self._counters = np.zeros(2, dtype=np.uint64)

    def close(self) -> None:
        if self._p:
            _lib.t1_sim_link_close(self._p)
            self._p = None

    def __del__(self) -> None:      # a simulator dropped without close(): its LCM receive thread goes too
        self.close()

    def sign_state(self, sender) -> None:
        """Sign every state from now on as this sender (messages.auth.Sender: the robot key)."""
        if not _lib.t1_sim_link_set_robot_key(self._p, sender.sender_id, sender.key, len(sender.key)):
            raise RuntimeError("OpenSSL could not key the state's HMAC-SHA256")

    def publish(self, channel: str, payload: bytes) -> None:
        _lib.t1_sim_link_publish(self._p, channel.encode(), payload, len(payload))

    def publish_state(self, utime_us: int, seq: int, quat, gyro, accel, q, dq, tau, status) -> None:
        arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (quat, gyro, accel, q, dq, tau)]
        status = np.ascontiguousarray(status, dtype=np.int32)
        _lib.t1_sim_link_publish_state(self._p, utime_us, seq, *(a.ctypes.data for a in arrays),
                                       status.ctypes.data)

    def poll(self, timeout_s: float) -> None:
        _lib.t1_sim_link_poll(self._p, timeout_s)

    def wait_for_answer(self, state_seq: int, timeout_s: float) -> bool:
        return bool(_lib.t1_sim_link_wait_for_answer(self._p, state_seq, timeout_s))

    def take_frames(self) -> bytes | None:
        """The newest valid command's 23 frames, once (None if none arrived since the last take)."""
        return self._frames.tobytes() if _lib.t1_sim_link_take_frames(self._p, self._frames.ctypes.data) else None

    def latest_payload(self) -> bytes | None:
        n = _lib.t1_sim_link_latest(self._p, self._payload.ctypes.data, MAX_COMMAND_BYTES)
        return self._payload[:n].tobytes() if n > 0 else None

    def counters(self) -> tuple[int, int]:
        """(commands received, commands dropped)."""
        _lib.t1_sim_link_counters(self._p, self._counters.ctypes.data)
        return int(self._counters[0]), int(self._counters[1])

    def last_drop_reason(self) -> str:
        return _lib.t1_sim_link_last_drop_reason(self._p).decode()


class _Plant(C.Structure):      # t1_sim_plant
    _fields_ = [("model", C.c_void_p), ("data", C.c_void_p), ("mj_step", C.c_void_p), ("buses", C.c_void_p),
                ("motors", C.c_void_p), ("host_q", C.c_void_p), ("host_dq", C.c_void_p), ("host_tau", C.c_void_p),
                ("host_status", C.c_void_p), ("substeps", C.c_int), ("quat_adr", C.c_int), ("gyro_adr", C.c_int),
                ("accel_adr", C.c_int)]


class _Faults(C.Structure):     # t1_sim_tick_faults
    _fields_ = [("dead_mask", C.c_uint32), ("cmd_drop_mask", C.c_uint32), ("reply_drop_mask", C.c_uint32),
                ("delay_cycles", C.c_uint32)]


def _mj_step_address() -> int:
    """mj_step of the MuJoCo library the Python bindings loaded (the same process-wide instance)."""
    lib = C.CDLL(str(next(Path(mujoco.__file__).parent.glob("libmujoco.so*"))))
    return C.cast(lib.mj_step, C.c_void_p).value


class LockstepTick:
    """Simulator.tick's lockstep path in one C++ call: the simulator's own model, data, buses, motors and
    host view, stepped in place."""

    def __init__(self, link: Link, model: mujoco.MjModel, data: mujoco.MjData, bus, substeps: int,
                 imu_adr: tuple[int, int, int]):
        self._link, self._keep = link, (model, data, bus)
        v = bus.view
        self._plant = _Plant(model._address, data._address, _mj_step_address(), bus.link.address,
                             bus.motors.address, v.q.ctypes.data, v.dq.ctypes.data, v.tau.ctypes.data,
                             v.status.ctypes.data, substeps, *imu_adr)
        self._faults = _Faults()
        self._plant_p, self._faults_p = C.addressof(self._plant), C.addressof(self._faults)

    def _set_faults(self, dead_mask: int, cmd_drop_mask: int, reply_drop_mask: int, delay_cycles: int) -> None:
        f = self._faults
        f.dead_mask, f.cmd_drop_mask, f.reply_drop_mask, f.delay_cycles = (
            dead_mask, cmd_drop_mask, reply_drop_mask, delay_cycles)

    def __call__(self, seq: int, wait_s: float, dead_mask: int = 0, cmd_drop_mask: int = 0,
                 reply_drop_mask: int = 0, delay_cycles: int = 0) -> bool:
        """One tick; True if the command answering state `seq` arrived within wait_s."""
        self._set_faults(dead_mask, cmd_drop_mask, reply_drop_mask, delay_cycles)
        return bool(_lib.t1_sim_lockstep_tick(self._link._p, self._plant_p, self._faults_p, seq, wait_s))

    def run(self, seq0: int, n: int, wait_s: float, dead_mask: int = 0, delay_cycles: int = 0) -> int:
        """Ticks seq0 … seq0 + n − 1 under the same faults (no frame lost: a loss is drawn per tick); how many
        were answered within wait_s."""
        self._set_faults(dead_mask, 0, 0, delay_cycles)
        return _lib.t1_sim_lockstep_ticks(self._link._p, self._plant_p, self._faults_p, seq0, n, wait_s)
