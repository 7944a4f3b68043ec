"""Prone starts for stage 1 (ours, a reverse curriculum; the seed's stage 1 starts fallen): settled states
along a hand-made path from the kneel forward onto hands and knees and down to lying face down.

Why: from the floor, stage 1 reached the kneel only from lying on its back (sitting up onto its heels); a
robot lying face down never pushed up, and starts along the kneel's forward collapse did not teach it: that
fall reaches the floor within 0.5 s, so its states jump from the kneel to prone (training/LESSONS.md, period 5).
Here every start is at rest, and the path's middle is a stable posture a policy can learn to leave first:
hands and knees, from which the kneel is a push back onto the heels.

The path, by progress p in [0, 2]: joint angles and the trunk's forward pitch piecewise linear between
  p = 0  the `kneel` keyframe, trunk upright;
  p = 1  hands and knees: the kneel with the trunk pitched forward by θ = hands_knees_pitch_rad, the hips
         flexed by θ more (thighs stay vertical) and the arms raised forward by θ (shoulder pitch −θ: they
         point at the floor); held by the shared PD gains it rests on hands, knees and toes;
  p = 2  lying face down with the default pose's joint angles (pitch π/2): where the runtime's PREPARE ramp
         leaves a robot that fell on its front.
A start: p ~ U(min_progress, max_progress), joint targets at p + U(±target_noise_rad) (clipped to the joint
ranges), placed on the floor at rest and held with the shared PD gains for settle_s [s] in C MuJoCo with the
CPU backend's motor callback (R6 and the firmware's motor law; a one-off host computation whatever backend
trains). Settled (16 noisy starts per progress): below p ≈ 0.6 the robot tips forward onto its chest (its hands
do not reach the floor before its weight passes the knees); p ≈ 0.7 … 1.3 rests on hands and knees, trunk at
0.38–0.43 m (the kneel's 0.405 m); beyond p ≈ 1.35 it lies on its chest: a start there must push up.
"""
from __future__ import annotations

import functools

import numpy as np
from ml_collections import config_dict

from common import model as t1model
from training.envs.fallen import backend_model
from training.envs.start_path import place_on_floor

PATH_END = 2.0          # progress of lying face down
PRONE_PITCH_RAD = np.pi / 2
HIPS = ("Left_Hip_Pitch", "Right_Hip_Pitch")                  # flexed θ more than the kneel's: thighs vertical
SHOULDERS = ("Left_Shoulder_Pitch", "Right_Shoulder_Pitch")   # at −θ: the arms point at the floor


def path_points(model, hands_knees_pitch_rad: float) -> list[tuple[float, np.ndarray, float]]:
    """[(progress, qpos, trunk pitch [rad])] of the path's three waypoints (module docstring)."""
    kneel = t1model.keyframe_qpos(model, "kneel")
    prone = t1model.keyframe_qpos(model, "home")
    theta = float(hands_knees_pitch_rad)
    if not 0.0 < theta <= PRONE_PITCH_RAD:
        raise ValueError(f"prone_starts.hands_knees_pitch_rad must be in (0, π/2], got {theta}")
    hands_knees = kneel.copy()
    for name in HIPS:
        hands_knees[model.joint(name).qposadr[0]] -= theta
    for name in SHOULDERS:
        hands_knees[model.joint(name).qposadr[0]] = -theta
    return [(0.0, kneel, 0.0), (1.0, hands_knees, theta), (PATH_END, prone, PRONE_PITCH_RAD)]


def pose_at(points, progress: float) -> tuple[np.ndarray, float]:
    """(qpos with its root not yet placed, trunk pitch [rad]) at `progress` on the path."""
    if not 0.0 <= progress <= PATH_END:
        raise ValueError(f"prone-path progress must be in [0, {PATH_END}], got {progress}")
    (p0, a, pa), (p1, b, pb) = next(seg for seg in zip(points[:-1], points[1:]) if progress <= seg[1][0])
    t = (progress - p0) / (p1 - p0)
    return (1.0 - t) * a + t * b, (1.0 - t) * pa + t * pb


def prone_config() -> config_dict.ConfigDict:
    """Stage 1's prone starts: this share of the getup env's fallen starts is instead a settled state along
    kneel (0) → hands and knees (1, trunk pitched forward hands_knees_pitch_rad) → lying face down (2), at
    progress U(min_progress, max_progress), joint targets ± target_noise_rad, held settle_s [s]."""
    return config_dict.create(prob=0.0, min_progress=0.0, max_progress=2.0, bank_starts=256, seed=800_000,
                              hands_knees_pitch_rad=1.4, target_noise_rad=0.1, settle_s=1.0)


def prone_starts(env, group) -> tuple[np.ndarray, np.ndarray]:
    return prone_bank(int(group.bank_starts), int(group.seed), float(group.min_progress), float(group.max_progress),
                      hands_knees_pitch_rad=float(group.hands_knees_pitch_rad),
                      target_noise_rad=float(group.target_noise_rad), settle_s=float(group.settle_s),
                      supervisor=env.host_supervisor())


def prone_bank(num_starts: int, seed: int, min_progress: float, max_progress: float, *,
               hands_knees_pitch_rad: float, target_noise_rad: float, settle_s: float,
               supervisor: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(qpos [num_starts, nq], qvel [num_starts, nv]) settled starts (module docstring); read-only, cached.
    supervisor = (max target speed [rad/s], joint-range fraction) of rule R6."""
    return _bank(int(num_starts), int(seed), float(min_progress), float(max_progress), float(hands_knees_pitch_rad),
                 float(target_noise_rad), float(settle_s), tuple(float(x) for x in supervisor))


@functools.lru_cache(maxsize=4)
def _bank(num_starts, seed, min_progress, max_progress, hands_knees_pitch_rad, target_noise_rad, settle_s,
          supervisor):
    from training.envs import cpu_backend    # heavy (JAX); only where a bank is rolled

    if num_starts < 1:
        raise ValueError(f"prone_starts.bank_starts must be >= 1, got {num_starts}")
    if not 0.0 <= min_progress <= max_progress <= PATH_END:
        raise ValueError(f"prone_starts: need 0 <= min_progress <= max_progress <= {PATH_END}, got "
                         f"{min_progress}, {max_progress}")
    if target_noise_rad < 0.0 or settle_s <= 0.0:
        raise ValueError(f"prone_starts: target_noise_rad must be >= 0 and settle_s > 0, got {target_noise_rad}, "
                         f"{settle_s}")
    mj = backend_model(*t1model.pd_gains(t1model.load_model()))
    points = path_points(mj, hands_knees_pitch_rad)
    rng = np.random.default_rng(seed)
    ranges = t1model.joint_ranges(mj)
    joints = slice(t1model.ROOT_QPOS, t1model.ROOT_QPOS + t1model.NUM_JOINTS)
    starts, targets = [], []
    for progress in rng.uniform(min_progress, max_progress, num_starts):
        q, pitch = pose_at(points, progress)
        q = q.copy()
        q[joints] = np.clip(q[joints] + rng.uniform(-target_noise_rad, target_noise_rad, t1model.NUM_JOINTS),
                            ranges[:, 0], ranges[:, 1])
        starts.append(place_on_floor(mj, q, pitch))
        targets.append(q[joints])
    speed, fraction = supervisor
    physics = cpu_backend.CpuPhysics(mj, 1, supervisor=(speed * mj.opt.timestep, fraction))
    b = physics.evaluation_batch(num_starts)
    b.qpos[:], b.qvel[:], b.time[:] = np.stack(starts), 0.0, 0.0
    physics.write_targets(b, np.stack(targets), np.stack(targets))
    for _ in range(int(round(settle_s / mj.opt.timestep))):
        b.step(nstep=1)
    out = np.array(b.qpos, np.float32), np.array(b.qvel, np.float32)
    for array in out:
        array.flags.writeable = False
    return out


def render_strip(out_png: str, size: int = 11, px: int = 200) -> None:
    """Side view of `size` settled starts at evenly spaced progress 0 … 2 (no noise), left to right, as one PNG."""
    from common.render import save_side_strip
    from training.envs.getup_config import default_config
    cfg = default_config()
    c, sup = cfg.prone_starts, cfg.supervisor
    model = t1model.load_model()
    qpos = np.stack([prone_bank(1, 0, p, p, hands_knees_pitch_rad=c.hands_knees_pitch_rad, target_noise_rad=0.0,
                                settle_s=c.settle_s, supervisor=(sup.max_target_speed_rps, sup.joint_range_fraction))[0][0]
                     for p in np.linspace(0.0, PATH_END, size)])
    save_side_strip(model, qpos, out_png, lookat_m=(0.2, 0.0, 0.25), elevation_deg=-15.0, px=px)


if __name__ == "__main__":   # MUJOCO_GL=osmesa python -m training.envs.prone_path OUT.png
    import sys
    if len(sys.argv) != 2:
        sys.exit("usage: python -m training.envs.prone_path OUT.png  (a strip of starts along the path)")
    render_strip(sys.argv[1])
