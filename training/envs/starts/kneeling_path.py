"""Reverse curriculum for the stand task (getup_stand.py; ours, not the seed's): starts along a path from standing
to the kneel.

Why: stage 2 from the kneel alone (the seed's start) learns to hold the kneel and never stands
(training/LESSONS.md). Standing up from this model's kneel (both knees and both toe tips
on the floor, feet behind) needs a lunge — one foot brought forward flat, then a push up over it — and
every exploratory move toward it that tips the robot ends the episode. Starting some episodes part of the
way up lets PPO learn the end of the motion first and extend it backward (Florensa et al. 2017, "Reverse
curriculum generation"); the full task (§4.5) later starts at the seed's fallen / kneeling / standing.

The path, by "progress" p in [0, 2]: joint angles piecewise linear between waypoints, trunk upright, lowest
point on the floor.
  p = 0     standing (the `home` keyframe)
  p = 1     half kneel: right leg as the kneel, left foot forward flat on the floor (left hip pitch −1.5,
            knee 2.2, ankle −0.7 rad; foot pitch hip + knee + ankle = 0): the flat-footed left leg whose sole is
            level with the right knee, a pose the PD gains hold (tests/test_kneeling_path.py).
  p = 1 … 2 the left leg swings back to the kneel with its knee lifted and its shin folded (knee up to the
            joint's 2.34 rad, ankle at −0.87), so the right knee stays on the floor, as when a person kneeling
            on both knees brings one foot forward; a straight blend from the half kneel to the kneel would push
            the left toes through the floor and lift the right knee.
  p = 2     the `kneel` keyframe.
Waypoints: config.reverse_curriculum.left_leg_waypoints, rows of (progress, left hip pitch, knee, ankle pitch).
"""
from __future__ import annotations

import sys

import mujoco
import numpy as np
from ml_collections import config_dict

from common import model as t1model
from common.render import save_side_strip

PATH_END = 2.0   # progress of the kneel
LEFT_LEG = ("Left_Hip_Pitch", "Left_Knee_Pitch", "Left_Ankle_Pitch")


def path_config() -> config_dict.ConfigDict:
    """The stand task's reverse curriculum. max_progress 0 = off: every episode starts at the kneel, as in the
    seed's stage 2. Else a start is drawn at progress U{min_progress … max_progress} along the path, or at the
    kneel with kneel_prob, from a bank of `bank_size` points; min_progress > 0 spends the starts on the part still
    to learn (the swing, p 1 … 2). left_leg_waypoints: rows of (progress, left hip pitch, knee, ankle pitch
    [rad]); 1.0 is the half kneel, the rest swing the leg back with the knee lifted (module docstring)."""
    return config_dict.create(
        max_progress=0.0, min_progress=0.0, kneel_prob=0.25, bank_size=41,
        left_leg_waypoints=[[1.0, -1.5, 2.2, -0.7], [1.3, -1.4, 2.3, -0.87], [1.5, -1.2, 2.34, -0.87],
                            [1.6, -0.9, 2.34, -0.87], [1.68, -0.75, 2.34, -0.87], [1.75, -0.5, 2.3, -0.05]])


def with_left_leg(model: mujoco.MjModel, kneel_qpos: np.ndarray, left_leg_rad) -> np.ndarray:
    """The kneel with the left leg's (hip pitch, knee, ankle pitch) [rad] replaced, before floor placement."""
    q = np.array(kneel_qpos, dtype=np.float64)
    for name, angle in zip(LEFT_LEG, left_leg_rad, strict=True):
        q[model.joint(name).qposadr[0]] = angle
    return q


def path_points(model: mujoco.MjModel, home: np.ndarray, kneel: np.ndarray, waypoints) -> list:
    """[(progress, qpos)] from standing (0) through the left-leg waypoints to the kneel (2)."""
    rows = [tuple(float(x) for x in w) for w in waypoints]
    progress = [0.0] + [r[0] for r in rows] + [PATH_END]
    if any(len(r) != 1 + len(LEFT_LEG) for r in rows) or np.any(np.diff(progress) <= 0):
        raise ValueError("reverse_curriculum.left_leg_waypoints: rows of (progress, hip pitch, knee, ankle "
                         f"pitch) with progress rising strictly inside (0, {PATH_END}), got {list(waypoints)}")
    return ([(0.0, np.asarray(home, np.float64))] + [(r[0], with_left_leg(model, kneel, r[1:])) for r in rows]
            + [(PATH_END, np.asarray(kneel, np.float64))])


def pose_at(points: list, progress: float) -> np.ndarray:
    """qpos at `progress` on the path (root pose not yet placed)."""
    if not 0.0 <= progress <= PATH_END:
        raise ValueError(f"start-path progress must be in [0, {PATH_END}], got {progress}")
    # the first segment that reaches `progress` (the last one ends at PATH_END, so one always does)
    (p0, a), (p1, b) = next(seg for seg in zip(points[:-1], points[1:]) if progress <= seg[1][0])
    t = (progress - p0) / (p1 - p0)
    return (1.0 - t) * a + t * b


def place_on_floor(model: mujoco.MjModel, qpos: np.ndarray, pitch_rad: float = 0.0) -> np.ndarray:
    """qpos at the origin, trunk pitched forward by pitch_rad (0 upright), root height such that the lowest
    robot primitive touches z = 0."""
    q = np.array(qpos, dtype=np.float64)
    q[0:3], q[3:7] = 0.0, (np.cos(pitch_rad / 2.0), 0.0, np.sin(pitch_rad / 2.0), 0.0)
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    q[2] = -t1model.lowest_robot_point(model, data)
    return q


def path_bank(model: mujoco.MjModel, home: np.ndarray, kneel: np.ndarray, waypoints, size: int) -> np.ndarray:
    """(size, nq) placed starts at evenly spaced progress 0 … 2; the last one is the kneel."""
    if size < 2:
        raise ValueError(f"start-path bank_size must be ≥ 2, got {size}")
    points = path_points(model, home, kneel, waypoints)
    return np.stack([place_on_floor(model, pose_at(points, p)) for p in np.linspace(0.0, PATH_END, size)])


def bank_range(min_progress: float, max_progress: float, size: int) -> slice:
    """The bank entries at min_progress ≤ progress ≤ max_progress (the ones a start is drawn from)."""
    if not 0.0 <= min_progress <= max_progress <= PATH_END or max_progress == 0.0:
        raise ValueError(f"reverse_curriculum: need 0 ≤ min_progress ≤ max_progress ≤ {PATH_END} and "
                         f"max_progress > 0, got min_progress {min_progress}, max_progress {max_progress}")
    per_entry = PATH_END / (size - 1)
    return slice(int(np.ceil(min_progress / per_entry - 1e-9)), int(np.floor(max_progress / per_entry + 1e-9)) + 1)


def render_strip(out_png: str, size: int = 21, px: int = 200) -> None:
    """Side view of `size` placed starts along the path, left to right standing → kneel, as one PNG."""
    model = t1model.load_model()
    bank = path_bank(model, t1model.keyframe_qpos(model, "home"), t1model.keyframe_qpos(model, "kneel"),
                     path_config().left_leg_waypoints, size)
    save_side_strip(model, bank, out_png, lookat_m=(0.0, 0.0, 0.35), elevation_deg=-5.0, px=px)


if __name__ == "__main__":   # MUJOCO_GL=osmesa python -m training.envs.starts.kneeling_path OUT.png
    if len(sys.argv) != 2:
        sys.exit("usage: python -m training.envs.starts.kneeling_path OUT.png  (a strip of starts along the path)")
    render_strip(sys.argv[1])
