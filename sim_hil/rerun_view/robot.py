"""The robot in 3-D for Rerun: the project model's own collision primitives (common/model.py), one entity per
geom under `robot/geoms/`, its shape logged once (static) and its world pose per joint state.

A pose is the MuJoCo forward kinematics of (trunk position, trunk orientation, the 23 logged joint angles).
The IMU sits at the Trunk origin with the Trunk's axes (site `imu` in t1.xml), so its quaternion is the
free joint's orientation. The position comes from the simulator's status; a real robot's log has none, so
the trunk is held at the nominal standing height above the origin and the view's trunk label says so."""
from __future__ import annotations

import mujoco
import numpy as np
import rerun as rr

from common.model import ROOT_QPOS, load_model, robot_geom_mask
from messages import contract

GEOMS_PATH = "robot/geoms"
TRUNK_GEOM = "trunk"
POSE_FROM_SIM = "trunk pose: simulator position + IMU orientation"
POSE_FROM_IMU = ("trunk pose: IMU orientation only (no simulator status in this run: position held at the "
                 f"nominal standing height {contract.NOMINAL_STANDING_TRUNK_HEIGHT_M} m)")


class RobotGeoms:
    """The model's robot geoms and their world poses for batches of (trunk pos, trunk quat, q)."""

    def __init__(self):
        self.model = load_model()
        self.data = mujoco.MjData(self.model)
        self.ids = np.flatnonzero(robot_geom_mask(self.model))
        self.names = [self.model.geom(g).name or f"geom_{g}" for g in self.ids]

    def entity(self, k: int) -> str:
        return f"{GEOMS_PATH}/{self.names[k]}"

    def log_shapes(self, rec: rr.RecordingStream, pose_note: str) -> None:
        """Each geom's shape in its own frame, static. `pose_note` labels the trunk (where its pose comes from)."""
        solid = rr.components.FillMode.Solid
        for k, g in enumerate(self.ids):
            size, kind = self.model.geom_size[g], self.model.geom_type[g]
            rgba = (np.clip(self.model.geom_rgba[g], 0, 1) * 255).astype(np.uint8)
            label = {"labels": [pose_note], "show_labels": True} if self.names[k] == TRUNK_GEOM else {}
            if kind == mujoco.mjtGeom.mjGEOM_BOX:
                shape = rr.Boxes3D(half_sizes=[size[:3]], colors=[rgba], fill_mode=solid, **label)
            elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:   # MuJoCo: centred on z, half-length size[1]
                shape = rr.Capsules3D(lengths=[2 * size[1]], radii=[size[0]], translations=[[0, 0, -size[1]]],
                                      colors=[rgba], fill_mode=solid, **label)
            elif kind == mujoco.mjtGeom.mjGEOM_SPHERE:
                shape = rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=[rgba], fill_mode=solid, **label)
            else:
                raise ValueError(f"geom {self.names[k]!r}: type {kind} has no Rerun shape here")
            rec.log(self.entity(k), shape, static=True)

    def poses(self, trunk_pos: np.ndarray, trunk_quat: np.ndarray, q: np.ndarray):
        """World positions (N, G, 3) [m] and orientations (N, G, 4) (x y z w, Rerun's order) of the geoms for N
        rows of trunk position (N, 3) [m], orientation (N, 4) (w x y z) and joint angles (N, 23) [rad]."""
        n, bodies = len(q), self.model.geom_bodyid[self.ids]
        pos = np.empty((n, len(self.ids), 3))
        body_quat = np.empty((n, len(self.ids), 4))
        qpos = self.data.qpos
        for i in range(n):
            qpos[0:3], qpos[3:7] = trunk_pos[i], trunk_quat[i]
            qpos[ROOT_QPOS:ROOT_QPOS + contract.NUM_JOINTS] = q[i]
            mujoco.mj_kinematics(self.model, self.data)
            pos[i] = self.data.geom_xpos[self.ids]
            body_quat[i] = self.data.xquat[bodies]
        return pos, _wxyz_to_xyzw(_quat_mul(body_quat, self.model.geom_quat[self.ids]))

    def send_poses(self, rec: rr.RecordingStream, times: list, trunk_pos, trunk_quat, q) -> None:
        """One Transform3D per row and geom, on the given time columns."""
        if len(q) == 0:
            return
        pos, quat = self.poses(np.asarray(trunk_pos, float), np.asarray(trunk_quat, float), np.asarray(q, float))
        for k in range(len(self.ids)):
            rec.send_columns(self.entity(k), indexes=times,
                             columns=rr.Transform3D.columns(translation=pos[:, k], quaternion=quat[:, k]))


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of (..., 4) quaternions, w x y z."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(np.broadcast_to(b, a.shape), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def _wxyz_to_xyzw(quat: np.ndarray) -> np.ndarray:
    return quat[..., [1, 2, 3, 0]]
