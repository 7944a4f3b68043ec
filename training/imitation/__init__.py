"""Stage 1 (fallen → kneel) by imitation: DAgger with the rise planner (training/planner/) as a closed-loop
teacher. The planner's rise is a knife edge that only its replanning holds, so behaviour cloning of its stored
rises drifts off them; here the learner's own states are labelled by short planner takeovers from them.

config.py  the settings;  expert.py  the batched takeovers (the labels);  learner.py  the policy network, its
fit and export;  dataset.py  the aggregated data on disk;  dagger.py  the rounds;  report.py  the campaign's
table and curve;  finetune.py  RL from the DAgger policy (PPO with a decaying BC term on the same data);
__main__  `python -m training.imitation`."""
from __future__ import annotations


def build(overrides: list[str]):
    """(DAgger config, teacher, getup env) with `key=value` overrides; `planner.`-prefixed ones go to the
    planner, whose horizon is the expert's."""
    from training.imitation import config, expert
    from training.overrides import apply_overrides
    from training.planner import batch as planner_batch
    cfg = config.default_config()
    ours = [o for o in overrides if not o.startswith("planner.")]
    theirs = [o.split(".", 1)[1] for o in overrides if o.startswith("planner.")]
    apply_overrides({"dagger": cfg}, ours)
    _, env, planner = planner_batch.build([f"horizon_s={cfg.expert.horizon_s}", *theirs])
    import training.evaluate  # noqa: F401  (imported now: a long run must not pick up code edited meanwhile)
    import training.evaluate_cpu  # noqa: F401
    return cfg, expert.Teacher(planner, cfg.expert), env


def run(out, overrides: list[str], demos=None, rounds: int | None = None, max_minutes: float | None = None,
        eval_dir=None, refit: bool = False, policy=None, lying: str = "") -> dict:
    """DAgger into the campaign folder `out` (dagger.run) with `key=value` overrides; returns its state."""
    from training.imitation import dagger
    cfg, teacher, env = build(overrides)
    return dagger.run(out, demos or dagger.DEFAULT_DEMOS, cfg, teacher, env, rounds, max_minutes, eval_dir, refit,
                      policy, lying)
