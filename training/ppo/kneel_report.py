"""A stage-1 PPO run's figures per checkpoint (`python -m training kneel-report --run RUN`): each kept checkpoint
not yet in the report is exported and evaluated on the batch from fallen seeds (evaluate.kneel_figures: reached
the kneel, in the kneeling posture, face down / on the back, held), one row per checkpoint in RUN/report.json and
RUN/report.md, which the recipe's campaign keeps beside the curve. A run keeps only its last few checkpoints, so
a campaign calls it while it runs."""
from __future__ import annotations

import json
from pathlib import Path

from training.core import checkpoints
from training.distill.finetune import bc_weight
from training.envs.starts.demos import demo_seeds
from training.evaluation.batch import kneel_figures
from training.imitation.report import table
from training.ppo.train import export_checkpoint

ROWS = "report.json"
REPORT = "report.md"
COLUMNS = (("env_steps", "env steps"), ("mean_of", "mean of the policies at"), ("bc_weight", "BC weight"),
           ("reached_kneel", "reached the kneel"),
           ("face_down", "… face down"), ("on_back", "… on the back"),
           ("kneeled", "the gate in the kneeling posture"), ("kneeled_face_down", "… face down"),
           ("kneeled_on_back", "… on the back"), ("kneeled_unseen", "… from seeds it never started from"),
           ("unseen_seeds", "(of seeds)"), ("kneel_held", "… held ≥ 1 s (of those)"),
           ("median_peak_trunk_m", "median peak trunk height [m]"))


def report(run_dir, seeds: int = 200, seconds: float = 8.0, steps: list[int] | None = None, like=None,
           mean: bool = False, log=print) -> list[dict]:
    """Evaluate the kept checkpoints of `run_dir` (or those at `steps`) missing from its report, and with `mean`
    the mean of their policies (export_checkpoint); returns the rows."""
    run_dir = Path(run_dir)
    state = checkpoints.load_run_state(run_dir)
    path = run_dir / ROWS
    rows = json.loads(path.read_text()) if path.exists() else []
    done = {_key(r) for r in rows}
    chosen = sorted([checkpoints.checkpoint_steps(p) for p in checkpoints.list_checkpoints(run_dir)]
                    if steps is None else steps)
    for group in [[n] for n in chosen] + ([chosen] if mean and len(chosen) > 1 else []):
        row = {"env_steps": group[-1], "seeds": seeds, "seconds": seconds, "bc_weight": _bc_weight(state, group[-1]),
               **({"mean_of": group} if len(group) > 1 else {})}
        if _key(row) in done:
            continue
        name = f"checkpoint_{'_'.join(map(str, group))}"
        artifact = export_checkpoint(run_dir, group, name, like=like)
        figures = kneel_figures(artifact, run_dir / "evaluations" / name.removeprefix("checkpoint_"), seeds,
                                seconds, f"python -m training kneel-report --run {run_dir}", seen_seeds(state))
        artifact.unlink()
        rows.append({**row, **figures})
        rows.sort(key=lambda r: (r["seeds"], r["seconds"], r["env_steps"], len(r.get("mean_of", ()))))
        path.write_text(json.dumps(rows, indent=1))
        (run_dir / REPORT).write_text(markdown(state, rows))
        log(f"kneel-report: {run_dir.name} at {name.removeprefix('checkpoint_')} env steps: {json.dumps(figures)}")
    return rows


def _key(row: dict) -> tuple:
    return row["env_steps"], row["seeds"], row["seconds"], tuple(row.get("mean_of", ()))


def seen_seeds(state: dict) -> frozenset[int]:
    """The fallen seeds a getup_kneel run's episodes may have started from: its bank of fallen starts, and with
    demonstration starts every demonstration's seed (its start is the demonstration's first state)."""
    env = state["env_config"]
    fallen = env["fallen"]
    seen = set(range(int(fallen["seed"]), int(fallen["seed"]) + int(fallen["bank_starts"])))
    demo = env.get("demo_starts", {})
    if float(demo.get("prob", 0.0)) > 0:
        seen |= set(demo_seeds(checkpoints.repo_path(demo["folder"])))
    return frozenset(seen)


def _bc_weight(state: dict, env_steps: int) -> float | None:
    """The BC term's weight at a checkpoint of a fine-tune from the imitation policy (None: no term)."""
    t = state["ppo_config"].get("imitation", {})
    if not t.get("bc_weight"):
        return None
    return round(float(bc_weight(float(env_steps), float(t["bc_weight"]), int(t.get("bc_decay_steps", 0)))), 3)


def markdown(state: dict, rows: list[dict]) -> str:
    text = [f"# {state['name']}: stage 1 per checkpoint\n",
            f"Started from `{state.get('init')}`; batch evaluation from fallen seeds (training/evaluation/batch.py)."]
    for seeds, seconds in sorted({(r["seeds"], r["seconds"]) for r in rows}):
        text += [f"\n## {seeds} fallen seeds × {seconds:g} s\n",
                 table([r for r in rows if (r["seeds"], r["seconds"]) == (seeds, seconds)], COLUMNS)]
    return "\n".join(text)
