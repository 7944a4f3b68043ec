"""The planner's waypoints: joint poses made from the kneel keyframe, and what the trunk does when the robot rests
on the floor in each (heights and up_z, the cost's targets)."""
from __future__ import annotations

import mujoco
import numpy as np

from common import events
from common import model as t1model
from messages.contract import JOINT_NAMES, NUM_JOINTS, joint_index
from training.envs.starts.kneeling_path import place_on_floor

WAYPOINTS = ("hands_knees", "heel_sit", "kneel")
HIP_PITCHES, KNEE_PITCHES = events.HIP_PITCHES, events.KNEE_PITCHES
SHOULDER_PITCHES = ("Left_Shoulder_Pitch", "Right_Shoulder_Pitch")
LEGS = slice(joint_index("Left_Hip_Pitch"), NUM_JOINTS)      # contract order: head, arms, waist, then the legs
assert all(JOINT_NAMES[LEGS][i].startswith(("Left_", "Right_")) for i in range(NUM_JOINTS - LEGS.start))


def indices(names) -> np.ndarray:
    """Contract indices of joints."""
    return np.array([joint_index(n) for n in names])


def pose(model, name: str, cfg) -> tuple[np.ndarray, float]:
    """(joint angles [rad], contract order; trunk pitch [rad]) of a waypoint:
    kneel        the model's `kneel` keyframe, trunk upright;
    hands_knees  the kneel pitched forward by cfg.hands_knees_pitch_rad, hips flexed as much more (thighs stay
                 vertical) and the arms pointing at the floor (shoulder pitch −pitch);
    heel_sit     the kneel with knees and hips flexed cfg.heel_sit_flex_rad more: sitting back on the heels,
                 trunk upright."""
    q = t1model.kneel_pose(model).copy()
    pitch = 0.0
    if name == "hands_knees":
        pitch = float(cfg.hands_knees_pitch_rad)
        q[indices(HIP_PITCHES)] -= pitch
        q[indices(SHOULDER_PITCHES)] = -pitch
    elif name == "heel_sit":
        q[indices(KNEE_PITCHES)] += float(cfg.heel_sit_flex_rad)
        q[indices(HIP_PITCHES)] -= float(cfg.heel_sit_flex_rad)
    elif name != "kneel":
        raise ValueError(f"planner: unknown waypoint {name!r} ({', '.join(WAYPOINTS)})")
    lo, hi = model.jnt_range[1:1 + NUM_JOINTS].T
    return np.clip(q, lo, hi), pitch


def targets(model, name: str, cfg) -> dict:
    """A waypoint's cost targets: joint angles q, and the trunk's height h (at the kneel at least the gate's
    height + cfg.kneel_height_margin_m), the waist's h_waist [m] and the trunk's up_z when it rests on the floor
    in that pose; joint_weight, the pose cost's per joint; upright_weight, the orientation cost's."""
    q, pitch = pose(model, name, cfg)
    qpos = t1model.keyframe_qpos(model, "kneel")
    qpos[t1model.ROOT_QPOS:t1model.ROOT_QPOS + NUM_JOINTS] = q
    d = mujoco.MjData(model)
    d.qpos[:] = place_on_floor(model, qpos, pitch)
    mujoco.mj_kinematics(model, d)
    w, kneel = cfg.weights, name == "kneel"
    weight = np.full(NUM_JOINTS, float(w.pose_kneel if kneel else w.pose))
    weight[LEGS] = float(w.leg_pose_kneel if kneel else w.leg_pose)
    h = float(d.xpos[model.body("Trunk").id, 2])
    if kneel:
        h = max(h, events.KNEEL_GATE_HEIGHT_M + float(cfg.kneel_height_margin_m))
    return {"name": name, "h": h, "h_waist": float(d.xpos[model.body("Waist").id, 2]),
            "up_z": float(d.site_xmat[model.site("imu").id, 8]), "q": q, "joint_weight": weight,
            "upright_weight": float(w.upright_kneel if kneel else w.upright)}
