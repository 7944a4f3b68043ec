"""Per-tick physics log of a trial and the metrics computed from it: the seed's Table 4.3 effort metrics
(common/effort.py), foot slips (puddles) and "ran to stabilise" (pushes). Definitions are in each function's docstring.

The log keeps per-tick reductions over the 23 joints (not 23-wide arrays): a 60 s trial is 30 000 ticks.
"""
from __future__ import annotations

import math

import mujoco
import numpy as np

from common import effort
from common.events import FALLEN_TRUNK_HEIGHT_M, heading_from_quat, kneeling_posture, up_z_from_quat
from common.model import ROOT_QPOS, trunk_forward_z
from sim_hil import config

FOOT_BODIES = ("left_foot_link", "right_foot_link")
# Slip: a loaded foot sliding. 50 N is a sixth of the robot's weight (31.6 kg · 9.81 = 310 N): a foot that
# carries real load, not one touching down or lifting off. 0.3 m/s held for 20 ms is sliding, not the few
# millimetres a box foot creeps while it settles.
SLIP_LOAD_N = 50.0
SLIP_SPEED_MPS = 0.3
SLIP_MIN_S = 0.02
# Ran to stabilise: no fall, and the trunk kept moving >= 0.3 m/s horizontally for >= 1 s with no command.
# A push (10-40 N·s, 0.3-1.3 m/s) absorbed in place is braked within a step (< 0.5 s); a robot that
# has to run it off keeps its speed for several steps.
RUN_SPEED_MPS = 0.3
RUN_MIN_S = 1.0


class TickLog:
    """What physics knew at the end of each control tick k (after the step that answered state k)."""

    FIELDS = ("t", "trunk", "waist", "up_z", "forward_z", "kneeling", "base_x", "base_y", "yaw", "fwd_vel", "speed_xy",
              "power", "tau_max", "tau_sum", "qacc_max", "qacc_sum", "contact_n")

    def __init__(self, model: mujoco.MjModel, n_ticks: int):
        self.n = n_ticks
        for name in self.FIELDS:
            setattr(self, name, np.zeros(n_ticks))
        self.mode = np.full(n_ticks, -1, dtype=np.int8)
        self.foot_load = np.zeros((n_ticks, 2))
        self.foot_speed = np.zeros((n_ticks, 2))
        self._model = model
        self._trunk = model.body("Trunk").id
        self._waist = model.body("Waist").id
        self._feet = [model.body(b).id for b in FOOT_BODIES]
        self._robot_geom = model.geom_bodyid != 0
        self._geom_foot = np.full(model.ngeom, -1)
        for i, b in enumerate(self._feet):
            self._geom_foot[model.geom_bodyid == b] = i
        self._prev_feet = None
        self._force = np.zeros(6)

    def record(self, k: int, data: mujoco.MjData, runtime_mode: int) -> None:
        dt = config.LOOP_PERIOD_S
        self.t[k] = data.time
        self.trunk[k] = data.xpos[self._trunk, 2]
        self.waist[k] = data.xpos[self._waist, 2]
        self.up_z[k] = up_z_from_quat(data.xquat[self._trunk])
        self.forward_z[k] = trunk_forward_z(data.qpos)           # how it lies: common.events.lying_side
        self.kneeling[k] = kneeling_posture(data.qpos[ROOT_QPOS:])   # 1: both knees down (stage 1's posture)
        self.base_x[k], self.base_y[k] = data.qpos[0], data.qpos[1]
        yaw = heading_from_quat(data.qpos[3:7])   # [rad], wrapped
        self.yaw[k] = yaw
        vx, vy = data.qvel[0], data.qvel[1]
        self.fwd_vel[k] = math.cos(yaw) * vx + math.sin(yaw) * vy   # as sim_status_t.forward_velocity
        self.speed_xy[k] = math.hypot(vx, vy)
        tau, dq, qacc = data.ctrl, data.qvel[6:], data.qacc[6:]       # motor torque [N·m], [rad/s], [rad/s²]
        self.power[k] = float(np.abs(tau * dq).sum())
        abs_tau, abs_acc = np.abs(tau), np.abs(qacc)
        self.tau_max[k], self.tau_sum[k] = abs_tau.max(), abs_tau.sum()
        self.qacc_max[k], self.qacc_sum[k] = abs_acc.max(), abs_acc.sum()
        self.mode[k] = runtime_mode
        total, feet = 0.0, [0.0, 0.0]
        for i in range(data.ncon):
            c = data.contact[i]
            g1, g2 = c.geom1, c.geom2
            if self._robot_geom[g1] == self._robot_geom[g2]:
                continue                                   # self-contact: internal, not a ground force
            mujoco.mj_contactForce(self._model, data, i, self._force)
            normal = abs(self._force[0])
            total += normal
            foot = self._geom_foot[g1 if self._robot_geom[g1] else g2]
            if foot >= 0:
                feet[foot] += normal
        self.contact_n[k] = total
        self.foot_load[k] = feet
        pos = data.xpos[self._feet, :2]
        if self._prev_feet is not None:
            self.foot_speed[k] = np.linalg.norm(pos - self._prev_feet, axis=1) / dt
        self._prev_feet = pos.copy()


def effort_metrics(log: TickLog, begin: int, end: int) -> dict[str, float]:
    """The seed's Table 4.3 (common/effort.py: definitions and names) over ticks [begin, end), from what physics
    knew at the end of each 2 ms control tick."""
    if not 0 <= begin < end <= log.n:
        raise ValueError(f"effort_metrics: window [{begin}, {end}) outside the {log.n} logged ticks")
    w = slice(begin, end)
    return effort.effort_metrics(log.power[w], log.power[w], log.tau_max[w], log.tau_sum[w], log.qacc_max[w],
                                 log.qacc_sum[w], log.contact_n[w], dt_s=config.LOOP_PERIOD_S)


def _runs(mask: np.ndarray, min_len: int) -> int:
    """Number of runs of True at least min_len samples long."""
    if mask.size == 0:
        return 0
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int(np.sum(ends - starts >= min_len))


def slip_events(log: TickLog, window: slice) -> int:
    """Slips: per foot, runs of >= SLIP_MIN_S where the foot carries >= SLIP_LOAD_N of ground contact force
    and its origin moves >= SLIP_SPEED_MPS horizontally; both feet counted."""
    min_len = max(1, int(round(SLIP_MIN_S / config.LOOP_PERIOD_S)))
    load, speed = log.foot_load[window], log.foot_speed[window]
    return sum(_runs((load[:, f] >= SLIP_LOAD_N) & (speed[:, f] >= SLIP_SPEED_MPS), min_len) for f in range(2))


def ran_to_stabilise(log: TickLog, window: slice) -> bool:
    """True when the robot never fell in the window and its trunk kept >= RUN_SPEED_MPS horizontal speed
    for >= RUN_MIN_S at a stretch (it ran the push off instead of absorbing it in place)."""
    trunk = log.trunk[window]
    if trunk.size == 0 or np.any(trunk < FALLEN_TRUNK_HEIGHT_M):
        return False
    return _runs(log.speed_xy[window] >= RUN_SPEED_MPS, int(round(RUN_MIN_S / config.LOOP_PERIOD_S))) > 0
