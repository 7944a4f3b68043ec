"""The planner as DAgger's expert, timed: a round of `training.imitation` (its rollouts and takeover labels) from
a few fallen starts, with the learner fitted to the stored demonstrations' first pairs. Its env-steps/s N (control
steps of single simulations, the takeovers' candidates included, per wall second) against the raw physics rate M
of the same batches (their steps over the time inside `Batch.step`), R = N / M, and the CPU seconds per label
(target ≤ 0.1)."""
from __future__ import annotations

import time

import numpy as np

STARTS = 8               # fallen starts of the timed round
ROLLOUT_S = 0.8          # two segments of the default takeover (2 replans of 0.1 s each)
FIT_PAIRS = 2048         # demonstration pairs the learner is fitted to first (a policy that moves, not a random one)
TARGET_CPU_S_PER_LABEL = 0.1


def planner_row(seed: int = 123) -> str:
    from training.imitation import dagger, dataset, expert
    from training.imitation.campaign import build
    from training.imitation.learner import fit, new_learner
    cfg, teacher, env = build([])
    obs, q = dataset.demonstration_pairs(dagger.DEFAULT_DEMOS)
    obs, q = obs[:FIT_PAIRS], q[:FIT_PAIRS]
    p = teacher.p
    learner = new_learner(obs, list(cfg.fit.hidden_layer_sizes), 0, env.manifest_fields(), p.lo, p.hi)
    cfg.fit.steps = 200
    learner, _ = fit(learner, obs, learner.label_actions(q), cfg.fit, 0)
    qpos, qvel = (a.astype(np.float64) for a in env.fallen_starts(STARTS, seed))
    expert.PROFILE.reset()
    t0 = time.monotonic()
    got = dagger.collect(teacher, learner, qpos, qvel, 0.0, ROLLOUT_S, np.random.default_rng(seed))
    wall = time.monotonic() - t0
    prof = expert.PROFILE
    n_rate, m_rate = prof.env_steps / wall, prof.env_steps / prof.physics_s
    per_label = got["cpu_s"] / len(got["obs"])
    verdict = "met" if per_label <= TARGET_CPU_S_PER_LABEL else "NOT met"
    return (f"planner   env-steps/s {n_rate:,.0f} = {n_rate / m_rate:.2f} of the raw physics rate "
            f"({m_rate:,.0f}); {len(got['obs'])} labels at {per_label:.3f} CPU s each "
            f"(target ≤ {TARGET_CPU_S_PER_LABEL:g}: {verdict})")


if __name__ == "__main__":
    print(planner_row())
