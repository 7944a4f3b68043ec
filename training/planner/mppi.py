"""MPPI over PD-target knots on the batched C physics: one robot, and `samples` copies of it that try plans.

A plan is K knots of the 23 joint targets [rad], knot_dt_s apart; the target of control step j is linear
between knots (knot 0 is "now"). Every replan_every_s the copies start from the robot's exact state (qpos,
qvel, warm start, R6's last targets), each follows the plan plus Gaussian knot noise (copy 0: the plan itself)
over the horizon, and the plan becomes their average weighted by exp(−(cost − best) / (λ·spread)) (MPPI).
The robot then runs the first replan_every_s of it, recorded step by step, and the plan shifts by as many
knots. Every step, robot and copies alike, is the training backend's: n_substeps × (R6, firmware PD law).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from common import events
from common import observation as obsdef
from training.envs import sagittal
from training.planner import costs, keyframes


@dataclass
class Demonstration:
    """One planned rise, per control step t (T steps; states have T + 1 rows: before each step and after the
    last). obs: the getup actor's observation (TERMS_GETUP, unnormalised) of each state; targets: the
    joint targets sent at step t (the getup env's action is (targets - default pose) / action scale)."""
    seed: int
    qpos: np.ndarray           # (T + 1, nq)
    qvel: np.ndarray           # (T + 1, nv)
    obs: np.ndarray            # (T + 1, 52)
    targets: np.ndarray        # (T, 23) [rad]
    trunk_height: np.ndarray   # (T + 1,) [m]
    up_z: np.ndarray           # (T + 1,)
    gate: np.ndarray           # (T + 1,) bool: §4.8's gate
    kneeling: np.ndarray       # (T + 1,) bool: the gate's posture (common/events.kneeling_posture)
    waypoint: np.ndarray       # (T + 1,) index of the keyframe the cost aimed at (config.waypoints)
    energy_J: float            # Σ |τ·q̇|·dt over the rise and hold
    cpu_s: float               # process CPU time of the plan
    ctrl_dt: float

    @property
    def gate_time_s(self) -> float | None:
        """When the gate first held in the kneeling posture, or None."""
        hit = np.flatnonzero(self.gate & self.kneeling)
        return float(hit[0] * self.ctrl_dt) if hit.size else None


class Planner:
    """MPPI rises toward the kneel for one physics (a CpuPhysics: model, n_substeps, R6 settings) and config."""

    def __init__(self, physics, cfg, default_pose: np.ndarray, action_scale):
        self.physics, self.cfg = physics, cfg
        m = self.model = physics.model
        self.nu, self.sub = m.nu, physics.n_substeps
        self.ctrl_dt = float(m.opt.timestep) * self.sub
        self.spk = _whole(cfg.knot_dt_s / self.ctrl_dt, "knot_dt_s / the control step")
        self.K = _whole(cfg.horizon_s / cfg.knot_dt_s, "horizon_s / knot_dt_s") + 1
        self.H = (self.K - 1) * self.spk
        self.replan_knots = _whole(cfg.replan_every_s / cfg.knot_dt_s, "replan_every_s / knot_dt_s")
        if not 1 <= self.replan_knots < self.K:
            raise ValueError("planner: replan_every_s must be at least one knot and shorter than the horizon")
        if cfg.samples < 2:
            raise ValueError(f"planner: samples must be at least 2, got {cfg.samples}")
        # target of step j: knots at (j + 1) / spk, linear between them
        f = np.arange(1, self.H + 1) / self.spk
        lo = np.minimum(np.floor(f).astype(int), self.K - 2)
        self.interp = np.zeros((self.H, self.K))
        self.interp[np.arange(self.H), lo] = 1.0 - (f - lo)
        self.interp[np.arange(self.H), lo + 1] = f - lo
        self.lo, self.hi = m.jnt_range[1:1 + self.nu, 0], m.jnt_range[1:1 + self.nu, 1]
        self.trunk, self.waist = m.body("Trunk").id, m.body("Waist").id
        self.imu = m.site("imu").id
        self.sensor = {n: slice(int(m.sensor(n).adr[0]), int(m.sensor(n).adr[0] + m.sensor(n).dim[0]))
                       for n in ("orientation", "gyro")}
        self.keyframes = [keyframes.targets(m, name, cfg) for name in cfg.waypoints]
        if not self.keyframes or cfg.waypoints[-1] != "kneel":
            raise ValueError(f"planner: waypoints must end at the kneel, got {list(cfg.waypoints)}")
        self.target = self.keyframes[-1]
        if cfg.sagittal_from and cfg.sagittal_from not in cfg.waypoints:
            raise ValueError(f"planner: sagittal_from {cfg.sagittal_from!r} is not a waypoint "
                             f"({', '.join(cfg.waypoints)})")
        self.sagittal_from = (list(cfg.waypoints).index(cfg.sagittal_from) if cfg.sagittal_from
                              else len(cfg.waypoints))
        self.expansion = sagittal.expansion()                         # (23, pitch values)
        self.default_pose, self.action_scale = np.asarray(default_pose), np.asarray(action_scale)
        self.samples = physics.evaluation_batch(int(cfg.samples))

    def _reached(self, keyframe: dict, r: dict) -> bool:
        return bool(abs(r["h"][0] - keyframe["h"]) < self.cfg.advance_height_m
                    and abs(r["up_z"][0] - keyframe["up_z"]) < self.cfg.advance_up_z)

    # ------------------------------------------------------------------ readings
    def readings(self, b) -> dict:
        n = b.qpos.shape[0]
        xpos = np.asarray(b.xpos).reshape(n, -1, 3)
        return {"h": xpos[:, self.trunk, 2], "h_waist": xpos[:, self.waist, 2],
                "up_z": np.asarray(b.site_xmat).reshape(n, -1, 9)[:, self.imu, 8],
                "q": b.qpos[:, 7:7 + self.nu], "dq": b.qvel[:, 6:6 + self.nu],
                "tau": np.asarray(b.actuator_force), "root_vel": b.qvel[:, :6]}

    def near(self, h) -> np.ndarray:
        return np.abs(h - self.target["h"]) < self.cfg.near_m

    # ------------------------------------------------------------------ one plan
    def mirrored(self, plan: np.ndarray) -> np.ndarray:
        """A plan in the sagittal space: each pitch pair at its mean, every other joint at home."""
        e = self.expansion
        pitch = (plan - self.default_pose) @ e / e.sum(axis=0)
        return self.default_pose + pitch @ e.T

    def improve(self, robot, plan: np.ndarray, sigma: float, rng: np.random.Generator, target: dict,
                mirrored: bool = False) -> np.ndarray:
        """The plan after one MPPI update from the robot's current state, toward the keyframe `target`
        (mirrored: the noise in the sagittal space, the plan already in it)."""
        s, nu = int(self.cfg.samples), self.nu
        if mirrored:
            noise = rng.standard_normal((s, self.K, self.expansion.shape[1])) @ self.expansion.T * sigma
        else:
            noise = rng.standard_normal((s, self.K, nu)) * sigma
        noise[0] = 0.0
        cand = np.clip(plan[None] + noise, self.lo, self.hi)
        traj = np.einsum("hk,skj->shj", self.interp, cand)
        b = self.samples
        b.time[:], b.qpos[:], b.qvel[:] = robot.time[0], robot.qpos[0], robot.qvel[0]
        b.qacc_warmstart[:] = robot.qacc_warmstart[0]
        b.userdata[:, nu:2 * nu] = robot.userdata[0, nu:2 * nu]      # R6's last targets
        total = np.zeros(s)
        w = self.cfg.weights
        for j in range(self.H):
            self.physics.write_targets(b, traj[:, j])
            b.step(nstep=self.sub)
            r = self.readings(b)
            near = self.near(r["h"]) if target is self.target else np.zeros(s, bool)
            c = costs.step_cost(r, target, w, near)
            total += c * (float(w.terminal) if j == self.H - 1 else 1.0)
        total = np.where(np.isfinite(total), total, np.inf)
        best, spread = total.min(), np.ptp(total[np.isfinite(total)])
        weight = np.exp(-(total - best) / (float(self.cfg.temperature) * spread + 1e-12))
        return np.tensordot(weight / weight.sum(), cand, axes=1)

    # ------------------------------------------------------------------ a rise
    def rise(self, qpos0: np.ndarray, qvel0: np.ndarray, last_target0: np.ndarray, seed: int) -> Demonstration:
        """Plan and run a rise from one start until the gate has held hold_s in the kneeling posture, or
        max_seconds have passed."""
        cfg, nu = self.cfg, self.nu
        rng = np.random.default_rng(seed)
        cpu0 = time.process_time()
        robot = self.physics.evaluation_batch(1)
        robot.qpos[:], robot.qvel[:], robot.time[:], robot.qacc_warmstart[:] = qpos0, qvel0, 0.0, 0.0
        self.physics.write_targets(robot, last_target0, last_target0)
        robot.forward()
        plan = np.tile(np.clip(qpos0[7:7 + nu], self.lo, self.hi), (self.K, 1))   # hold where PREPARE left it
        rows: dict[str, list] = {k: [] for k in ("qpos", "qvel", "orientation", "gyro", "h", "up_z", "q", "waypoint")}
        targets, energy = [], 0.0
        max_steps = int(round(cfg.max_seconds / self.ctrl_dt))
        hold_steps = int(round(cfg.hold_s / self.ctrl_dt))
        first_gate, waypoint = None, 0

        def record():
            r = self.readings(robot)
            for k, v in (("qpos", robot.qpos[0]), ("qvel", robot.qvel[0]), ("h", r["h"][0]), ("up_z", r["up_z"][0]),
                         ("q", r["q"][0]), ("orientation", robot.sensordata[0, self.sensor["orientation"]]),
                         ("gyro", robot.sensordata[0, self.sensor["gyro"]]), ("waypoint", waypoint)):
                rows[k].append(np.array(v, np.float64))
            return r

        r = record()
        while True:
            # on to the waypoint after the furthest one reached (a robot already at the kneel stays there)
            reached = [k for k in range(waypoint, len(self.keyframes)) if self._reached(self.keyframes[k], r)]
            waypoint = min(reached[-1] + 1, len(self.keyframes) - 1) if reached else waypoint
            at_kneel = waypoint == len(self.keyframes) - 1
            sigma = cfg.sigma_near_rad if at_kneel and self.near(r["h"])[0] else cfg.sigma_rise_rad
            mirrored = waypoint >= self.sagittal_from
            if mirrored:
                plan = self.mirrored(plan)
            plan = self.improve(robot, plan, float(sigma), rng, self.keyframes[waypoint], mirrored)
            for q_des in self.interp[:self.replan_knots * self.spk] @ plan:
                self.physics.write_targets(robot, q_des[None])
                for _ in range(self.sub):        # the robot's energy, substep by substep (training/evaluation/cpu.py)
                    dq0 = robot.qvel[0, 6:6 + nu].copy()
                    robot.step(nstep=1)
                    energy += float(np.sum(np.abs(robot.actuator_force[0] * dq0))) * float(self.model.opt.timestep)
                targets.append(q_des)
                r = record()
                ok = costs.gate(r["h"], r["up_z"])[0] and self.kneeling(r["q"])[0]
                if ok and first_gate is None:
                    first_gate = len(targets)
                done = len(targets) >= (first_gate + hold_steps if first_gate is not None else max_steps)
                if done:
                    break
            if done:
                break
            plan = np.concatenate([plan[self.replan_knots:], np.repeat(plan[-1:], self.replan_knots, axis=0)])
        return self._demonstration(seed, rows, np.array(targets), energy, time.process_time() - cpu0)

    def kneeling(self, q) -> np.ndarray:
        return events.kneeling_posture(q, np, self.cfg.kneel_knee_min_rad, self.cfg.kneel_hip_min_rad)

    def _demonstration(self, seed, rows, targets, energy, cpu_s) -> Demonstration:
        a = {k: np.array(v) for k, v in rows.items()}
        state = obsdef.ObservationState(
            imu_quat=a["orientation"], gyro=a["gyro"], command=np.zeros((len(a["q"]), 3)), q=a["q"],
            dq=a["qvel"][:, 6:6 + self.nu], default_pose=self.default_pose, last_action=np.zeros_like(a["q"]),
            gait_phase=np.broadcast_to(obsdef.initial_gait_phase(np), (len(a["q"]), 2)))
        obs = obsdef.build_observation(obsdef.TERMS_GETUP, state, np)
        return Demonstration(
            seed=seed, qpos=a["qpos"], qvel=a["qvel"], obs=obs.astype(np.float32), targets=targets,
            trunk_height=a["h"], up_z=a["up_z"], gate=costs.gate(a["h"], a["up_z"]), kneeling=self.kneeling(a["q"]),
            waypoint=a["waypoint"].astype(int), energy_J=energy, cpu_s=cpu_s, ctrl_dt=self.ctrl_dt)


def _whole(x: float, what: str) -> int:
    n = int(round(x))
    if n < 1 or abs(x - n) > 1e-6:
        raise ValueError(f"planner: {what} must be a whole number >= 1, got {x:g}")
    return n

