"""The rise planner as a closed-loop teacher: from many robots' states at once, short planner takeovers whose
every step is a label (observation → the planner's joint targets).

Each replan is one MPPI update of training/planner/mppi.py's kind, batched over all N robots × S candidates in
one C batch: the candidates of a robot are the current policy's own closed-loop rollout over the horizon (its
targets at the knots: the policy's action sequence, GPC's policy samples), the expert's previous plan shifted
(the planner's warm-start chain) and noisy copies of both. The cost is the planner's (costs.step_cost toward
each robot's waypoint); after the update every robot runs the plan's first replan interval, recorded step by
step, and the next replan starts from there. A takeover of several replans is what the planner would do from
the learner's state, which one update of the learner's own plan is not (LESSONS: the DAgger probe)."""
from __future__ import annotations

from dataclasses import dataclass
from time import perf_counter

import numpy as np

from common import observation as obsdef
from training.planner import costs

STATE = ("time", "qpos", "qvel", "qacc_warmstart")


@dataclass
class StepProfile:
    """Control steps of single simulations the teacher's batches ran, and the seconds inside the C physics
    (tests/bench/train_bench.py's planner row: the rate against the raw physics rate)."""
    env_steps: int = 0
    physics_s: float = 0.0

    def reset(self) -> None:
        self.env_steps, self.physics_s = 0, 0.0


PROFILE = StepProfile()


class Robots:
    """N simulations of the training physics, with the planner's waypoint progress of each."""

    def __init__(self, physics, n: int):
        self.physics, self.n, self.nu = physics, n, physics.model.nu
        self.b = physics.evaluation_batch(n)

    def copy_from(self, other: "Robots", rows=None) -> None:
        """State, wanted targets and R6's last targets of `other`'s robots, row i of self from row rows[i]."""
        self._copy(other, np.arange(self.n), np.arange(self.n) if rows is None else rows)

    def take_rows(self, other: "Robots", mask: np.ndarray) -> None:
        """Rows where mask holds become other's same rows."""
        idx = np.flatnonzero(mask)
        if idx.size:
            self._copy(other, idx, idx)

    def _copy(self, other: "Robots", dst: np.ndarray, src: np.ndarray) -> None:
        for f in STATE:
            getattr(self.b, f)[dst] = getattr(other.b, f)[src]
        both = slice(0, 2 * self.nu)
        self.b.userdata[dst, both] = other.b.userdata[src, both]
        last = self.b.userdata[:, self.nu:2 * self.nu].copy()
        self.b.forward()        # fresh kinematics and sensors; its control callback moved R6's target: undone
        self.b.userdata[:, self.nu:2 * self.nu] = last

    def step(self, q_des: np.ndarray) -> None:
        self.physics.write_targets(self.b, q_des)
        t0 = perf_counter()
        self.b.step(nstep=self.physics.n_substeps)
        PROFILE.physics_s += perf_counter() - t0
        PROFILE.env_steps += self.n


class Teacher:
    """Batched takeovers by `planner` (a training.planner.mppi.Planner) from many robots; `policy(obs) → q_des`
    is the learner (numpy, (n, 52) → (n, 23) [rad])."""

    def __init__(self, planner, cfg):
        self.p, self.cfg = planner, cfg
        self.S = 2 + int(cfg.policy_samples) + int(cfg.plan_samples)
        m = planner.model
        self.obs_sensors = (planner.sensor["orientation"], planner.sensor["gyro"])
        self.nu = m.nu
        kf = planner.keyframes
        self.kf = {k: np.array([f[k] for f in kf]) for k in ("h", "h_waist", "up_z", "q", "joint_weight",
                                                               "upright_weight")}
        self.last_wp = len(kf) - 1
        self._pools: dict[int, Robots] = {}

    def start(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[Robots, np.ndarray, np.ndarray]:
        """Robots at fallen starts (R6 as the runtime's PREPARE leaves it), each plan holding the start's pose (as
        a rise starts) and the first waypoint: (robots, plans (n, K, 23), waypoints)."""
        p = self.p
        robots = Robots(p.physics, len(qpos))
        b = robots.b
        b.qpos[:], b.qvel[:], b.time[:], b.qacc_warmstart[:] = qpos, qvel, 0.0, 0.0
        p.physics.write_targets(b, p.default_pose[None], p.default_pose[None])
        b.forward()
        plans = np.repeat(np.clip(qpos[:, None, 7:7 + p.nu], p.lo, p.hi), p.K, axis=1)
        return robots, plans, np.zeros(len(qpos), int)

    # ------------------------------------------------------------------ readings
    def observe(self, robots: Robots) -> np.ndarray:
        """The getup actor's observation (TERMS_GETUP, unnormalised) of every robot, (n, 52) float32."""
        b, nu = robots.b, self.nu
        o, g = self.obs_sensors
        n = robots.n
        state = obsdef.ObservationState(
            imu_quat=b.sensordata[:, o], gyro=b.sensordata[:, g], command=np.zeros((n, 3)),
            q=b.qpos[:, 7:7 + nu], dq=b.qvel[:, 6:6 + nu], default_pose=self.p.default_pose,
            last_action=np.zeros((n, nu)), gait_phase=np.broadcast_to(obsdef.initial_gait_phase(np), (n, 2)))
        return obsdef.build_observation(obsdef.TERMS_GETUP, state, np).astype(np.float32)

    def advance_waypoints(self, robots: Robots, waypoint: np.ndarray) -> np.ndarray:
        """The planner's rule per robot: on to the waypoint after the furthest one reached; a robot that fell
        back to the floor (trunk below restart_below_m past the first waypoint) starts over at the first."""
        r = self.p.readings(robots.b)
        fell = (waypoint > 0) & (r["h"] < float(self.cfg.restart_below_m))
        waypoint = np.where(fell, 0, waypoint)
        reached = (np.abs(r["h"][:, None] - self.kf["h"][None]) < self.p.cfg.advance_height_m) & \
                  (np.abs(r["up_z"][:, None] - self.kf["up_z"][None]) < self.p.cfg.advance_up_z)
        reached &= np.arange(len(self.kf["h"]))[None] >= waypoint[:, None]
        furthest = np.where(reached.any(axis=1), reached.shape[1] - 1 - np.argmax(reached[:, ::-1], axis=1), -1)
        return np.where(furthest >= 0, np.minimum(furthest + 1, self.last_wp), waypoint)

    # ------------------------------------------------------------------ one replan of all robots
    def _pool(self, n: int) -> Robots:
        if n not in self._pools:
            self._pools[n] = Robots(self.p.physics, n)
        return self._pools[n]

    def proposal(self, robots: Robots, policy) -> np.ndarray:
        """The policy's own plan from every robot's state: its closed-loop targets over the horizon at the
        knots, (n, K, 23) (knot 0: its first target)."""
        p = self.p
        sim = self._pool(robots.n)
        sim.copy_from(robots)
        knots = np.zeros((robots.n, p.K, self.nu))
        for j in range(p.H):
            q_des = np.clip(policy(self.observe(sim)), p.lo, p.hi)
            if j == 0:
                knots[:, 0] = q_des
            if (j + 1) % p.spk == 0:
                knots[:, (j + 1) // p.spk] = q_des
            sim.step(q_des)
        return knots

    def improve(self, robots: Robots, plans: np.ndarray, proposals: np.ndarray, waypoint: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
        """One MPPI update of every robot's plan (n, K, 23) over its candidates (module docstring)."""
        p, n, S, nu = self.p, robots.n, self.S, self.nu
        r = p.readings(robots.b)
        at_kneel = waypoint == self.last_wp
        sigma = np.where(at_kneel & p.near(r["h"]), p.cfg.sigma_near_rad, p.cfg.sigma_rise_rad)
        mirrored = waypoint >= p.sagittal_from
        k_pol = int(self.cfg.policy_samples)
        base = np.concatenate([plans[:, None], proposals[:, None],
                               np.repeat(proposals[:, None], k_pol, axis=1),
                               np.repeat(plans[:, None], S - 2 - k_pol, axis=1)], axis=1)     # (n, S, K, nu)
        full = rng.standard_normal((n, S, p.K, nu))
        sag = rng.standard_normal((n, S, p.K, p.expansion.shape[1])) @ p.expansion.T
        noise = np.where(mirrored[:, None, None, None], sag, full) * sigma[:, None, None, None]
        noise[:, :2] = 0.0
        cand = base + noise
        cand = np.where(mirrored[:, None, None, None], p.mirrored(cand), cand)
        cand = np.clip(cand, p.lo, p.hi).reshape(n * S, p.K, nu)
        traj = np.einsum("hk,skj->shj", p.interp, cand)
        sims = self._pool(n * S)
        sims.copy_from(robots, np.repeat(np.arange(n), S))
        wp = np.repeat(waypoint, S)
        target = {k: v[wp] for k, v in self.kf.items()}
        kneel = wp == self.last_wp
        w = p.cfg.weights
        total = np.zeros(n * S)
        for j in range(p.H):
            sims.step(traj[:, j])
            rj = p.readings(sims.b)
            c = costs.step_cost(rj, target, w, kneel & p.near(rj["h"]))
            total += c * (float(w.terminal) if j == p.H - 1 else 1.0)
        total = np.where(np.isfinite(total), total, np.inf).reshape(n, S)
        finite = np.isfinite(total)
        best = np.where(finite, total, np.inf).min(axis=1, keepdims=True)
        worst = np.where(finite, total, -np.inf).max(axis=1, keepdims=True)
        spread = np.where(np.isfinite(worst - best), worst - best, 0.0)
        weight = np.exp(-(total - best) / (float(p.cfg.temperature) * spread + 1e-12))
        weight = np.where(finite, weight, 0.0)
        weight /= weight.sum(axis=1, keepdims=True)
        return np.einsum("ns,nskj->nkj", weight, cand.reshape(n, S, p.K, nu))

    # ------------------------------------------------------------------ a takeover
    def takeover(self, robots: Robots, plans: np.ndarray, waypoint: np.ndarray, policy,
                 rng: np.random.Generator) -> dict:
        """From the robots' states, takeover_replans replans of the planner, executed on `robots` (moved in
        place). Returns the labels {obs (n·L, 52), q_des (n·L, 23)}, the plans after it (shifted, the chain's
        next warm start), the waypoints and, per robot, whether §4.8's gate held in the kneeling posture after
        each step ("gate", (L, n))."""
        p = self.p
        obs, q, gate = [], [], []
        for _ in range(int(self.cfg.takeover_replans)):
            plans = self.improve(robots, plans, self.proposal(robots, policy), waypoint, rng)
            for q_des in np.einsum("hk,nkj->hnj", p.interp[:p.replan_knots * p.spk], plans):
                obs.append(self.observe(robots))
                q.append(q_des.astype(np.float32))
                robots.step(q_des)
                waypoint = self.advance_waypoints(robots, waypoint)
                gate.append(self.at_gate(robots))
            plans = np.concatenate([plans[:, p.replan_knots:],
                                    np.repeat(plans[:, -1:], p.replan_knots, axis=1)], axis=1)
        return {"obs": np.concatenate(obs), "q_des": np.concatenate(q), "plans": plans, "waypoint": waypoint,
                "gate": np.array(gate)}

    def at_gate(self, robots: Robots, readings: dict | None = None) -> np.ndarray:
        """Per robot: §4.8's gate holds in the kneeling posture (from `readings`, the planner's of these robots,
        where the caller has them)."""
        r = self.p.readings(robots.b) if readings is None else readings
        return costs.gate(r["h"], r["up_z"]) & self.p.kneeling(r["q"])
