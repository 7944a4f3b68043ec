"""CPU physics backend of the training envs: MuJoCo C over all cores, for machines without a GPU.

The envs (rewards, observations, resets, commands, pushes, metrics) stay the same jitted JAX code for
both backends; only `T1Env.make_data` / `physics_step` and the contact readings differ (base.py). Here:

* Physics: `mujoco.batch.Batch` steps every env of a batch on a thread pool (0 = all cores) in C,
  without the GIL. Each env is one simulation row; the batch is made once per batch size (training
  envs, eval envs) and kept.
* Motor law: the deployed runtime's target rule R6 and then firmware_like's `t1_motor_step` run at
  every physics substep as MuJoCo's control callback (training/cpu_physics/t1_mjcb_motor.c): the env
  writes the wanted q_des and the supervisor's last target [rad] into d->userdata, the callback moves
  that target and writes the clamped torque [N·m] into d->ctrl. kp / kd come from each simulation's
  actuator_biasprm, as in the MJX backend.
* JAX side: one `jax.pure_callback` per control step with vmap_method="expand_dims", so brax's
  vmapped env.step makes ONE host call for the whole batch. The host keeps no per-env state between
  calls: `HostData` carries the integration state (time, qpos, qvel, qacc_warmstart) through JAX, so
  anything JAX does to it (auto-reset by brax's wrappers, pushes that edit qvel) is what steps next.
  JAX holds it in float32, as MJX does; within a control step the C physics runs in float64.
* Readings: model sensors, qpos/qvel and the body/site poses both engines compute. Foot contacts come
  from MuJoCo contact sensors added to this backend's model (MJX reads its contact buffer instead).
* Domain randomisation: the same `randomization_fn` as MJX (training/envs/randomize.py), applied once
  per batch on the host: its per-world model fields are copied into the batch's per-simulation fields.
"""
from __future__ import annotations

import ctypes
import os
import threading
from dataclasses import dataclass
from pathlib import Path
from time import perf_counter

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import batch as mj_batch

from training.envs.randomize import RANDOMIZED_FIELDS

REPO_ROOT = Path(__file__).resolve().parents[2]
LIBRARY = Path("training") / "cpu_physics" / "libt1_mjcb_motor.so"   # under the CMake build folder
FOOT_FLOOR_SENSORS = ("left_foot_floor", "right_foot_floor")
FEET_SENSOR = "feet_touching"
CONTACT_FOUND = 1          # mjtConDataField bit: the contact sensor reports how many contacts it found
STATE_FIELDS = ("time", "qpos", "qvel", "qacc_warmstart")
READING_FIELDS = ("qacc", "sensordata", "xpos", "site_xpos", "site_xmat", "cvel", "actuator_force")


@dataclass
class HostProfile:
    """Where the host side of every CpuPhysics in this process spends its time [s] (tests/bench/train_bench.py's
    profile): stepping the C physics, and copying state in and out of the batch around it."""
    physics_s: float = 0.0
    copies_s: float = 0.0
    env_steps: int = 0       # control steps of single envs

    def reset(self) -> None:
        self.physics_s, self.copies_s, self.env_steps = 0.0, 0.0, 0


PROFILE = HostProfile()


@struct.dataclass
class HostData:
    """What JAX holds of one env's C simulation: its integration state and the readings the envs use,
    named and shaped as mjx.Data's fields (site_xmat 3×3) so env code reads either."""
    time: jax.Array
    qpos: jax.Array
    qvel: jax.Array
    qacc_warmstart: jax.Array
    qacc: jax.Array
    sensordata: jax.Array
    xpos: jax.Array
    site_xpos: jax.Array
    site_xmat: jax.Array
    cvel: jax.Array
    actuator_force: jax.Array


def library_path() -> Path:
    return Path(os.environ.get("T1_BUILD", str(REPO_ROOT / "build"))) / LIBRARY


_callback = {}   # the loaded library (kept alive while installed)


def install_motor_callback() -> ctypes.CDLL:
    """Make the firmware motor law MuJoCo's control callback (process-global; it ignores every model
    that was not built by `add_backend_elements`)."""
    if "lib" not in _callback:
        path = library_path()
        if not path.exists():
            raise FileNotFoundError(f"CPU backend: {path} is missing: run `make build` (or point T1_BUILD "
                                    "at the CMake build folder)")
        _callback["lib"] = ctypes.CDLL(str(path))
        _callback["lib"].t1_mjcb_marker.restype = ctypes.c_double
    mujoco.set_mjcb_control(_callback["lib"].t1_mjcb_motor)
    return _callback["lib"]


def add_backend_elements(spec: mujoco.MjSpec, foot_geoms, floor_geom: str) -> None:
    """userdata for the motor targets (+ the callback's marker) and the foot contact sensors."""
    lib = install_motor_callback()
    spec.nuserdata = lib.t1_mjcb_nuserdata()
    geom = mujoco.mjtObj.mjOBJ_GEOM
    for name, foot in zip(FOOT_FLOOR_SENSORS, foot_geoms):
        spec.add_sensor(name=name, type=mujoco.mjtSensor.mjSENS_CONTACT, objtype=geom, objname=foot,
                        reftype=geom, refname=floor_geom, intprm=[CONTACT_FOUND, 0, 1])
    spec.add_sensor(name=FEET_SENSOR, type=mujoco.mjtSensor.mjSENS_CONTACT, objtype=geom, objname=foot_geoms[0],
                    reftype=geom, refname=foot_geoms[1], intprm=[CONTACT_FOUND, 0, 1])


class CpuPhysics:
    """Batched C physics behind jax.pure_callback. `template`: the env's mjx.Model of the same robot
    (without this backend's extra elements), which the randomization_fn is applied to. `supervisor`: (max
    target step per substep [rad], joint-range fraction) of the runtime's target rule (t1_mjcb_motor.c)."""

    def __init__(self, mj_model: mujoco.MjModel, n_substeps: int, *, supervisor: tuple[float, float],
                 template=None, nthread: int = 0):
        self._lib = install_motor_callback()
        if mj_model.nuserdata != self._lib.t1_mjcb_nuserdata():
            raise ValueError("CpuPhysics: the model lacks the backend's userdata (add_backend_elements)")
        self.model, self.n_substeps, self.nthread = mj_model, int(n_substeps), int(nthread)
        self._template, self._randomize, self._seed = template, None, 0
        self._batches: dict[int, mj_batch.Batch] = {}
        self._lock = threading.Lock()      # a Batch must not be used from two threads at once
        sensors = {name: int(mj_model.sensor_adr[mj_model.sensor(name).id])
                   for name in (*FOOT_FLOOR_SENSORS, FEET_SENSOR)}
        self._foot_adr = np.array([sensors[n] for n in FOOT_FLOOR_SENSORS])
        self._feet_adr = sensors[FEET_SENSOR]
        d = mujoco.MjData(mj_model)
        self._shapes = {f: np.shape(getattr(d, f)) for f in (*STATE_FIELDS, *READING_FIELDS)}
        self._shapes["site_xmat"] = (mj_model.nsite, 3, 3)
        self._njoint = mj_model.nu
        self._supervisor = supervisor      # (max target step per substep [rad], joint-range fraction)

    def set_randomization(self, randomization_fn, seed: int) -> None:
        """brax's randomization_fn(mjx_model, rngs) -> (model, in_axes), applied to every batch made
        from now on, simulation i of a batch of n getting world i of PRNGKey(seed) split n ways."""
        if self._template is None:
            raise ValueError("CpuPhysics.set_randomization: no template mjx.Model to randomise")
        with self._lock:
            self._randomize, self._seed = randomization_fn, int(seed)
            self._batches.clear()

    # ---------------------------------------------------------------- host side
    def _batch(self, n: int) -> mj_batch.Batch:
        if n not in self._batches:
            b = self._new_batch(n, persistent=False)
            if self._randomize is not None:
                self._apply_randomization(b, n)
            self._batches[n] = b
        return self._batches[n]

    def _apply_randomization(self, b: mj_batch.Batch, n: int) -> None:
        """The MJX randomization_fn, evaluated once on the host; its per-world fields → per-simulation."""
        rngs = jax.random.split(jax.random.PRNGKey(self._seed), n)
        model_v, _ = self._randomize(self._template, rngs)
        for name in RANDOMIZED_FIELDS:
            per_sim = b.expand(name)
            per_sim[...] = np.asarray(getattr(model_v, name), per_sim.dtype).reshape(per_sim.shape)
        b.set_const()    # qpos0 and masses feed mj_setConst's derived constants

    def write_targets(self, b, q_des, last_target=None) -> None:
        """The wanted targets and (when given) the supervisor's last targets [rad] of every simulation of b
        (t1_mjcb_motor.c's userdata layout)."""
        nj = self._njoint
        b.userdata[:, :nj] = q_des
        if last_target is not None:
            b.userdata[:, nj:2 * nj] = last_target

    def _write(self, b, time, qpos, qvel, warm, q_des, last_target) -> None:
        b.time[:], b.qpos[:], b.qvel[:], b.qacc_warmstart[:] = time, qpos, qvel, warm
        self.write_targets(b, q_des, last_target)

    def read(self, b, lead) -> tuple:
        """HostData's fields of batch b (float32), shaped (*lead, ...)."""
        out = []
        for f in (*STATE_FIELDS, *READING_FIELDS):
            out.append(np.asarray(getattr(b, f), np.float32).reshape((*lead, *self._shapes[f])))
        return tuple(out)

    def host_step(self, time, qpos, qvel, warm, q_des, last_target):
        lead = qpos.shape[:-1]
        n = int(np.prod(lead))
        nj = self._njoint
        with self._lock:
            b = self._batch(n)
            t0 = perf_counter()
            self._write(b, time.reshape(n), qpos.reshape(n, -1), qvel.reshape(n, -1), warm.reshape(n, -1),
                        q_des.reshape(n, -1), last_target.reshape(n, -1))
            t1 = perf_counter()
            b.step(nstep=self.n_substeps)
            t2 = perf_counter()
            out = (*self.read(b, lead), np.asarray(b.userdata[:, nj:2 * nj], np.float32).reshape(*lead, nj))
            PROFILE.physics_s += t2 - t1
            PROFILE.copies_s += (t1 - t0) + (perf_counter() - t2)
            PROFILE.env_steps += n
            return out

    def host_reset(self, qpos, qvel):
        lead = qpos.shape[:-1]
        n = int(np.prod(lead))
        q = qpos.reshape(n, -1)
        # vmap's expand_dims passes an unbatched argument (e.g. a constant zero qvel) with lead 1
        qvel = np.broadcast_to(qvel, (*lead, qvel.shape[-1]))
        with self._lock:
            b = self._batch(n)
            # hold the start pose: targets = the joints' own positions
            hold = q[:, 7:7 + self._njoint]
            self._write(b, 0.0, q, qvel.reshape(n, -1), 0.0, hold, hold)
            b.forward()
            return self.read(b, lead)

    def _new_batch(self, n: int, persistent: bool) -> mj_batch.Batch:
        """n simulations, HostData's readings bound, the motor callback switched on for each."""
        b = mj_batch.Batch(self.model, n, self.nthread, persistent=persistent)
        for f in READING_FIELDS:     # a derived field is copied out only once bound, before the call
            b.bind(f)
        nj = self._njoint
        b.userdata[:, 2 * nj], b.userdata[:, 2 * nj + 1] = self._supervisor
        b.userdata[:, 2 * nj + 2] = self._lib.t1_mjcb_marker()
        return b

    def evaluation_batch(self, n: int) -> mj_batch.Batch:
        """A persistent batch (training/evaluation/cpu.py): each simulation's whole MjData, contacts
        included, stays readable after every step."""
        return self._new_batch(n, persistent=True)

    # ---------------------------------------------------------------- JAX side
    def _result_shapes(self, lead) -> tuple:
        return tuple(jax.ShapeDtypeStruct((*lead, *self._shapes[f]), jnp.float32)
                     for f in (*STATE_FIELDS, *READING_FIELDS))

    def make_data(self, qpos: jax.Array, qvel: jax.Array) -> HostData:
        out = jax.pure_callback(self.host_reset, self._result_shapes(qpos.shape[:-1]), qpos, qvel,
                                vmap_method="expand_dims")
        return HostData(*out)

    def step(self, data: HostData, q_des: jax.Array, last_target: jax.Array) -> tuple[HostData, jax.Array]:
        """One control step: n_substeps × (supervisor target and firmware PD in C → mj_step), all envs of
        the batch at once. Returns (data, the supervisor's last target [rad])."""
        lead = data.qpos.shape[:-1]
        shapes = (*self._result_shapes(lead), jax.ShapeDtypeStruct((*lead, self._njoint), jnp.float32))
        out = jax.pure_callback(self.host_step, shapes, data.time, data.qpos, data.qvel, data.qacc_warmstart,
                                q_des, last_target, vmap_method="expand_dims")
        return HostData(*out[:-1]), out[-1]

    def foot_contacts(self, data: HostData) -> jax.Array:
        """(left, right) foot touching the floor, from the contact sensors."""
        return data.sensordata[self._foot_adr] > 0.0

    def feet_touching(self, data: HostData) -> jax.Array:
        return data.sensordata[self._feet_adr] > 0.0
