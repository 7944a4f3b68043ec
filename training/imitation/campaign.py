"""A DAgger campaign with the rise planner as the teacher: its pieces built from `key=value` overrides (build) and
its rounds run into a campaign folder (run)."""
from __future__ import annotations

from training.planner import batch as planner_batch  # first: its renderer picks the offscreen GL before mujoco loads

# isort: split
import training.evaluation.batch  # noqa: F401  (imported now: a long run must not pick up code edited meanwhile)
import training.evaluation.cpu  # noqa: F401
from training.core.overrides import apply_overrides
from training.imitation import config, dagger, expert


def build(overrides: list[str]):
    """(DAgger config, teacher, getup env) with `key=value` overrides; `planner.`-prefixed ones go to the
    planner, whose horizon is the expert's."""
    cfg = config.default_config()
    ours = [o for o in overrides if not o.startswith("planner.")]
    theirs = [o.split(".", 1)[1] for o in overrides if o.startswith("planner.")]
    apply_overrides({"dagger": cfg}, ours)
    _, env, planner = planner_batch.build([f"horizon_s={cfg.expert.horizon_s}", *theirs])
    return cfg, expert.Teacher(planner, cfg.expert), env


def run(out, overrides: list[str], demos=None, rounds: int | None = None, max_minutes: float | None = None,
        eval_dir=None, refit: bool = False, policy=None, lying: str = "", rolled_by=None) -> dict:
    """DAgger into the campaign folder `out` (dagger.run) with `key=value` overrides; returns its state."""
    cfg, teacher, env = build(overrides)
    return dagger.run(out, demos or dagger.DEFAULT_DEMOS, cfg, teacher, env, rounds, max_minutes, eval_dir, refit,
                      policy, lying, rolled_by)
