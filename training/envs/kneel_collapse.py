"""Collapse starts for stage 1 (ours, a reverse curriculum; the seed's stage 1 starts fallen): states along
the robot's collapse from the kneel keyframe to the floor.

Why: a stage-1 policy that holds the kneel from the keyframe met the gate from 3 % of the states along the
harnessed rises (rise_bank.py) and from no fallen start (training/LESSONS.md, period 4): the rises arrive
moving, above the kneel, in postures the unassisted policy cannot hold. A collapse is the kneel's own way
down: early states are the kneel slightly tipped, late ones lie on the floor near the kneel's posture, and
`max_progress` (0 the kneel, 1 the end of the collapse) sets how far down the starts go, as start_path.py does
for stage 2 along a hand-made path.

`collapse_bank` starts at the kneel with a random tipping push (root angular velocity about a horizontal
axis at an angle U(push_axis_deg) from the world x axis, push_rad_s·U(0.5, 1) [rad/s]; axes in (0°, 180°)
tip it forward, face down) and the kneel's joint angles held with the shared PD gains × gain_scale, in C
MuJoCo with the CPU backend's motor callback (R6 and the firmware's motor law: a one-off host computation
whatever backend trains), and keeps the state of every control tick of the first duration_s [s]; progress is
tick / last tick.
"""
from __future__ import annotations

import functools

import numpy as np
from ml_collections import config_dict

from common import model as t1model
from training.envs.fallen import backend_model

PUSH_SPREAD = (0.5, 1.0)    # the push's magnitude as a fraction of push_rad_s, uniform in this range
ANY_AXIS_DEG = (0.0, 360.0)  # push_axis_deg: a tip in any horizontal direction


def collapse_config() -> config_dict.ConfigDict:
    """Stage 1's collapse starts: this share of the getup env's fallen starts is instead a state along the collapse
    from the kneel (PD gains × gain_scale, a tipping push of push_rad_s [rad/s] about an axis push_axis_deg [deg]
    from world x: (0, 180) tips it face down, duration_s [s]) of `bank_starts` starts, at progress 0 …
    max_progress toward the floor."""
    return config_dict.create(prob=0.0, max_progress=1.0, bank_starts=256, seed=700_000, gain_scale=0.1,
                              push_rad_s=2.0, duration_s=2.0, push_axis_deg=[0.0, 360.0])


def collapse_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    return collapse_bank(int(group.bank_starts), int(group.seed), float(group.max_progress),
                         gain_scale=float(group.gain_scale), push_rad_s=float(group.push_rad_s),
                         duration_s=float(group.duration_s), push_axis_deg=tuple(group.push_axis_deg),
                         ctrl_dt=float(env.dt), supervisor=env.host_supervisor())


def collapse_bank(num_starts: int, seed: int, max_progress: float, *, gain_scale: float,
                  push_rad_s: float, duration_s: float, ctrl_dt: float, supervisor: tuple[float, float],
                  push_axis_deg: tuple[float, float] = ANY_AXIS_DEG) -> tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) of the collapses from progress 0 to `max_progress` (module docstring); read-only arrays.
    supervisor = (max target speed [rad/s], joint-range fraction) of rule R6."""
    if not 0.0 <= max_progress <= 1.0:
        raise ValueError(f"collapse_starts.max_progress must be in [0, 1], got {max_progress}")
    qpos, qvel = _rollouts(num_starts, seed, gain_scale, push_rad_s, duration_s, ctrl_dt, supervisor, push_axis_deg)
    last = int(np.floor(max_progress * (qpos.shape[1] - 1) + 1e-9))
    bank = (qpos[:, :last + 1].reshape(-1, qpos.shape[-1]), qvel[:, :last + 1].reshape(-1, qvel.shape[-1]))
    for array in bank:
        array.flags.writeable = False
    return bank


def _rollouts(num_starts, seed, gain_scale, push_rad_s, duration_s, ctrl_dt, supervisor, push_axis_deg):
    """collapses() with its arguments in the types its cache keys on (a numpy or JAX scalar would miss it)."""
    return collapses(int(num_starts), int(seed), float(gain_scale), float(push_rad_s), float(duration_s),
                     float(ctrl_dt), tuple(float(x) for x in supervisor), tuple(float(x) for x in push_axis_deg))


@functools.lru_cache(maxsize=4)
def collapses(num_starts: int, seed: int, gain_scale: float, push_rad_s: float, duration_s: float, ctrl_dt: float,
              supervisor: tuple[float, float],
              push_axis_deg: tuple[float, float] = ANY_AXIS_DEG) -> tuple[np.ndarray, np.ndarray]:
    """The rollouts: qpos (starts, ticks + 1, nq), qvel (starts, ticks + 1, nv) [float32], tick 0 the kneel.
    Cached (read-only arrays): banks at other progresses pay nothing."""
    from training.envs import cpu_backend    # heavy (JAX); only where a bank is rolled

    if num_starts < 1:
        raise ValueError(f"collapse_starts.bank_starts must be >= 1, got {num_starts}")
    if not 0.0 < gain_scale <= 1.0:
        raise ValueError(f"collapse_starts.gain_scale must be in (0, 1] (weaker than the policy's PD), got {gain_scale}")
    if push_rad_s < 0.0 or duration_s <= 0.0:
        raise ValueError(f"collapse_starts: push_rad_s must be >= 0 and duration_s > 0, got {push_rad_s}, {duration_s}")
    if len(push_axis_deg) != 2 or not push_axis_deg[0] <= push_axis_deg[1]:
        raise ValueError(f"collapse_starts.push_axis_deg must be [low, high] with low <= high, got {push_axis_deg}")
    kp, kd = t1model.pd_gains(t1model.load_model())
    mj = backend_model(gain_scale * kp, gain_scale * kd)
    substeps = int(round(ctrl_dt / mj.opt.timestep))
    ticks = int(round(duration_s / ctrl_dt))
    if substeps < 1 or ticks < 1:
        raise ValueError(f"collapse_starts: ctrl_dt {ctrl_dt} s and duration_s {duration_s} s must each span a "
                         f"physics step of {mj.opt.timestep} s")
    speed, fraction = supervisor
    physics = cpu_backend.CpuPhysics(mj, substeps, supervisor=(speed * mj.opt.timestep, fraction))
    b = physics.evaluation_batch(num_starts)
    kneel = t1model.keyframe_qpos(mj, "kneel")
    rng = np.random.default_rng(seed)
    axis = rng.uniform(*np.radians(push_axis_deg), num_starts)
    rate = push_rad_s * rng.uniform(*PUSH_SPREAD, num_starts)
    b.qpos[:], b.qvel[:], b.time[:] = kneel, 0.0, 0.0
    root_w = slice(t1model.ROOT_QVEL - 3, t1model.ROOT_QVEL)       # the free joint's angular velocity
    b.qvel[:, root_w] = np.stack([rate * np.cos(axis), rate * np.sin(axis), np.zeros(num_starts)], axis=1)
    joints = kneel[t1model.ROOT_QPOS:t1model.ROOT_QPOS + t1model.NUM_JOINTS]
    physics.write_targets(b, joints, joints)
    qpos, qvel = [np.array(b.qpos, np.float32)], [np.array(b.qvel, np.float32)]
    for _ in range(ticks):
        b.step(nstep=substeps)
        qpos.append(np.array(b.qpos, np.float32))
        qvel.append(np.array(b.qvel, np.float32))
    out = np.stack(qpos, axis=1), np.stack(qvel, axis=1)
    for array in out:
        array.flags.writeable = False
    return out
