"""Best-of-K as the expert: from each fallen start, K rises of the current policy at once on the C physics, rise 0
as the policy acts and the others with smooth noise on its joint targets; the first that meets §4.8's gate in the
kneeling posture is the demonstration, its steps up to the gate plus the hold are labels (observation → the targets
it sent). The planner's takeovers label toward its own keyframe chain, which from the learner's states meets the
gate less often than the learner does (`python -m training.imitation.coverage`); a rise judged by the gate itself
is better than the learner wherever it labels (a success the policy nearly makes: self-imitation of its best
rises, from the starts where they fail). With `clean`, only rises without a failed getup attempt before the gate
(common/events' rule: the trunk fell back attempt_rise_m below an attempt's peak) are candidates: labels that rise
in one go, where the policy itself falls back and tries again."""
from __future__ import annotations

import time

import numpy as np

from common import events


def noise(rng: np.random.Generator, rises: int, steps: int, nu: int, sigma_rad: float, knot_steps: int) -> np.ndarray:
    """(steps, rises, nu) target noise [rad]: Gaussian knots knot_steps apart, linear in between."""
    knots = rng.standard_normal((steps // knot_steps + 2, rises, nu)) * sigma_rad
    f = np.arange(steps) / knot_steps
    lo = np.floor(f).astype(int)
    w = (f - lo)[:, None, None]
    return (1.0 - w) * knots[lo] + w * knots[lo + 1]


def failed_attempts(trunk_m: np.ndarray, up_z: np.ndarray, dt_s: float) -> int:
    """Failed getup attempts (common/events' rule) in a rise's trunk height [m] and up_z series, one per tick."""
    t = np.arange(1, len(trunk_m) + 1) * dt_s
    return sum(a.outcome == "failed" for a in events.getup_events(t, trunk_m, up_z).attempt_log)


def collect(teacher, policy, qpos: np.ndarray, qvel: np.ndarray, cfg, rollout_s: float,
            rng: np.random.Generator) -> dict:
    """One round's labels from the starts (qpos, qvel) by best-of-K (cfg: the expert's best_of_k group; `policy`:
    (n, 52) observations → (n, 23) joint targets [rad]). met_gate counts the starts whose best-of-K met the gate,
    policy_met_gate those where rise 0 (the policy itself) did; per start, the chosen rise's first time at the gate
    [s] (nan: none met it) and the longest it held there [s] (gate_time_s, held_s)."""
    p = teacher.p
    cpu0 = time.process_time()
    n, k = len(qpos), int(cfg.k)
    robots, _, _ = teacher.start(np.repeat(qpos, k, axis=0), np.repeat(qvel, k, axis=0))
    steps = int(round(rollout_s / p.ctrl_dt))
    hold = int(round(events.KNEEL_HOLD_S / p.ctrl_dt))
    dq = noise(rng, n * k, steps, p.nu, float(cfg.sigma_rad), max(1, int(round(float(cfg.knot_s) / p.ctrl_dt))))
    dq[:, ::k] = 0.0                                       # rise 0 of every start: the policy as it acts
    obs, q, gate = [], [], np.zeros((steps, n * k), bool)
    trunk_m, up_z = np.zeros((steps, n * k)), np.zeros((steps, n * k))
    for j in range(steps):
        o = teacher.observe(robots)
        q_des = np.clip(policy(o) + dq[j], p.lo, p.hi)
        obs.append(o)
        q.append(q_des.astype(np.float32))
        robots.step(q_des)
        r = p.readings(robots.b)
        gate[j] = teacher.at_gate(robots, r)
        trunk_m[j], up_z[j] = r["h"], r["up_z"]
    obs, q = np.stack(obs), np.stack(q)                    # (steps, n·k, ·)
    first = np.argmax(gate, axis=0)                        # per rise: the step whose result met the gate
    met = gate.any(axis=0)
    if bool(cfg.clean):
        met &= [m and failed_attempts(trunk_m[:f + 1, r], up_z[:f + 1, r], p.ctrl_dt) == 0
                for r, (m, f) in enumerate(zip(met, first))]
    met = met.reshape(n, k)                                # (n, k)
    labels_o, labels_q = [], []
    gate_time_s, held_s = np.full(n, np.nan), np.zeros(n)
    for i in np.flatnonzero(met.any(axis=1)):
        row = i * k + int(np.argmax(met[i]))
        end = min(int(first[row]) + 1 + hold, steps)
        labels_o.append(obs[:end, row])
        labels_q.append(q[:end, row])
        gate_time_s[i], held_s[i] = (first[row] + 1) * p.ctrl_dt, events.longest_run(gate[:, row]) * p.ctrl_dt
    return {"obs": np.concatenate(labels_o) if labels_o else np.zeros((0, obs.shape[-1]), np.float32),
            "q_des": np.concatenate(labels_q) if labels_q else np.zeros((0, p.nu), np.float32),
            "met_gate": int(met.any(axis=1).sum()), "policy_met_gate": int(met[:, 0].sum()),
            "gate_time_s": gate_time_s, "held_s": held_s,
            "cpu_s": time.process_time() - cpu0}
