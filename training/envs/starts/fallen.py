"""Seeded fallen start states for the getup tasks, precomputed on the host in C MuJoCo.

`common.model.fallen_state(model, seed)` drops the robot from a random pose and returns the settled
lying state; it is deterministic per seed, so a bank of starts is (seed, seed + 1, ...). Results are
cached in memory per seed, so a second env (or a test) asking for the same seeds pays nothing.

The runtime's hand-over (`prepare_s` > 0). In the loop the policy never sees the settled fall itself:
`t1-runtime --autostart` goes PASSIVE → DAMPING → PREPARE → POLICY, one tick each for the first two, and
PREPARE ramps the joint targets linearly from the measured pose to the policy's default pose over
prepare_s (runtime/src/safety_supervisor.cpp finish_tick) with the T1's stand-up gains (PREPARE_KP /
PREPARE_KD) under rule R6. A lying robot straightens its limbs during that ramp and may roll. So the
getup tasks start from the state after it, simulated here on sim_hil's robot (the loop's physics) with
the CPU backend's motor callback (R6 + firmware_like's motor law at every 2 ms tick). Why: a policy
trained from the settled fall met a different robot in the loop. Not modelled: the two
PASSIVE / DAMPING ticks (4 ms) and the bus latency; the first POLICY target is rate-limited from the
measured joint angles here, from the default pose in the runtime (they differ by PREPARE's tracking error).
"""
from __future__ import annotations

import functools

import mujoco
import numpy as np
from ml_collections import config_dict

from common import model as t1model
from common.artifact import RUNTIME_LOOP_DT_S
from common.events import LYING_SIDES, lying_side
from messages import contract
from training.envs import base, collision, cpu_backend

# The runtime's PREPARE (messages/contract.json supervisor.prepare, C++ reads the same): the T1's stand-up gains
# kp [N·m/rad] / kd [N·m·s/rad] in the contract's joint order, and the ramp `make eval-getup` runs [s].
PREPARE_KP = np.array(contract.PREPARE_KP_NM_PER_RAD)
PREPARE_KD = np.array(contract.PREPARE_KD_NMS_PER_RAD)
PREPARE_S = contract.PREPARE_DURATION_S


def fallen_config() -> config_dict.ConfigDict:
    """The getup tasks' fallen starts: `bank_starts` distinct seeded states (seeds `seed` …), each the state after
    the runtime's PREPARE ramp of `prepare_s` [s] (0 = the settled fall itself), drawn in proportion to the
    `side_weights` of the way each lies (face down, on the back, on its side: common/events.py's rule; whole
    numbers, 1 1 1 = as they fall, 0 = never)."""
    return config_dict.create(bank_starts=128, seed=0, prepare_s=PREPARE_S, side_weights=[1, 1, 1])


def weight_sides(qpos: np.ndarray, qvel: np.ndarray, weights) -> tuple[np.ndarray, np.ndarray]:
    """The bank (qpos [N, nq], qvel [N, nv]) with each start repeated by the weight of the way it lies
    (events.LYING_SIDES order): a uniform draw from it picks a start in proportion to its side's weight."""
    w = list(weights)
    if len(w) != len(LYING_SIDES) or any(isinstance(x, bool) or int(x) != x or x < 0 for x in w) or not any(w):
        raise ValueError(f"fallen.side_weights must be {len(LYING_SIDES)} whole numbers ≥ 0, not all 0 "
                         f"({', '.join(LYING_SIDES)}), got {w}")
    sides = [LYING_SIDES.index(lying_side(float(z))) for z in t1model.trunk_forward_z(qpos)]
    rows = np.repeat(np.arange(len(qpos)), [int(w[k]) for k in sides])
    if rows.size == 0:
        raise ValueError(f"fallen.side_weights {w}: no start of the bank lies on a side with a weight above 0")
    return qpos[rows], qvel[rows]


@functools.lru_cache(maxsize=1)
def _model():
    return t1model.load_model()


@functools.lru_cache(maxsize=None)
def _one(seed: int) -> tuple[np.ndarray, np.ndarray]:
    qpos, qvel = t1model.fallen_state(_model(), seed)
    qpos.flags.writeable = False
    qvel.flags.writeable = False
    return qpos, qvel


def _check(num, seed) -> None:
    if isinstance(num, bool) or not isinstance(num, (int, np.integer)) or num < 1:
        raise ValueError(f"fallen_states: num must be a positive int, got {num!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"fallen_states: seed must be a non-negative int, got {seed!r}")


def fallen_states(num: int, seed: int, prepare_s: float = 0.0,
                  supervisor: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(qpos [num, nq], qvel [num, nv]) of fallen states for seeds seed, seed + 1, ..., seed + num − 1:
    the settled fall, or with prepare_s > 0 the state after the runtime's PREPARE ramp of that length,
    under R6 with `supervisor` = (max target speed [rad/s], joint-range fraction)."""
    _check(num, seed)
    if not (isinstance(prepare_s, (int, float)) and 0.0 <= prepare_s <= 10.0):
        raise ValueError(f"fallen_states: prepare_s must be seconds in [0, 10] (the runtime's --prepare-s), "
                         f"got {prepare_s!r}")
    if prepare_s > 0 and supervisor is None:
        raise ValueError("fallen_states: prepare_s > 0 needs the supervisor settings (max target speed, range "
                         "fraction)")
    if prepare_s == 0:
        states = [_one(int(seed) + i) for i in range(int(num))]
        return np.stack([s[0] for s in states]), np.stack([s[1] for s in states])
    qpos, qvel = _prepared(int(num), int(seed), float(prepare_s), tuple(float(x) for x in supervisor))
    return qpos.copy(), qvel.copy()


@functools.lru_cache(maxsize=8)
def _prepared(num: int, seed: int, prepare_s: float, supervisor: tuple[float, float]):
    qpos, qvel = fallen_states(num, seed)
    return after_prepare(qpos, qvel, prepare_s, supervisor)


def backend_model(kp: np.ndarray, kd: np.ndarray) -> mujoco.MjModel:
    """sim_hil's robot with the CPU backend's motor callback and the PD gains kp [N·m/rad], kd [N·m·s/rad]."""

    spec = t1model.robot_spec()
    cpu_backend.add_backend_elements(spec, collision.FOOT_GEOMS, base.FLOOR_GEOM)
    mj = spec.compile()
    mj.actuator_biasprm[:, base.KP_SLOT] = kp
    mj.actuator_biasprm[:, base.KD_SLOT] = kd
    return mj


@functools.lru_cache(maxsize=1)
def _prepare_physics():
    """sim_hil's robot with the CPU backend's motor callback and the stand-up gains in the PD slots."""
    return backend_model(PREPARE_KP, PREPARE_KD)


def after_prepare(qpos: np.ndarray, qvel: np.ndarray, prepare_s: float,
                  supervisor: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """The states (qpos [N, nq], qvel [N, nv]) after the runtime's PREPARE ramp from each given state;
    supervisor = (max target speed [rad/s], joint-range fraction) of rule R6."""

    mj = _prepare_physics()
    tick_s = mj.opt.timestep                             # one physics step = one 2 ms runtime tick
    if abs(tick_s - RUNTIME_LOOP_DT_S) > 1e-12:
        raise ValueError(f"after_prepare: the model's timestep {tick_s} s is not the runtime tick "
                         f"{RUNTIME_LOOP_DT_S} s")
    ticks = int(round(prepare_s / tick_s))
    speed, fraction = supervisor
    physics = cpu_backend.CpuPhysics(mj, 1, supervisor=(speed * tick_s, fraction))
    b = physics.evaluation_batch(len(qpos))
    b.qpos[:], b.qvel[:], b.time[:] = qpos, qvel, 0.0
    start = np.asarray(qpos)[:, t1model.ROOT_QPOS:t1model.ROOT_QPOS + t1model.NUM_JOINTS]
    goal = t1model.default_pose(mj)
    physics.write_targets(b, start, start)               # PREPARE's first tick: last target = measured q
    for k in range(1, ticks + 1):
        physics.write_targets(b, start + (k / ticks) * (goal - start))
        b.step(nstep=1)
    return np.array(b.qpos), np.array(b.qvel)
