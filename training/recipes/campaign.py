"""A recipe's campaign kept across machines in training/campaigns/NAME/: each stage's newest checkpoint (or the one
it ended at), run state, curve and report, copied from runs/ (`recipe NAME --save-campaign`) and back
(`recipe NAME --resume` on a fresh clone); nothing else from runs/ is tracked."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from training.core import checkpoints
from training.ppo import kneel_report
from training.recipes import base as R
from training.recipes.stages import DISTILL_STATE, _rounds, end_checkpoint, referenced, stage_dirs, superseded

RUNS_ROOT = checkpoints.REPO_ROOT / "runs"
CAMPAIGNS_ROOT = checkpoints.REPO_ROOT / "training" / "campaigns"
CURVE_FILES = ("metrics.csv", "learning_curve.png")
REPORT_FILES = (kneel_report.REPORT, kneel_report.ROWS)   # a run's figures per checkpoint beside its curve
RUN_FILES = (checkpoints.RUN_STATE, DISTILL_STATE, *CURVE_FILES, *REPORT_FILES)   # what a kept stage copies


def save_campaign(name: str, root: Path = RUNS_ROOT, campaigns: Path = CAMPAIGNS_ROOT) -> list[Path]:
    """Copy each run stage's newest checkpoint (with end_at: the one it ended at), run state, curve and report
    into campaigns/NAME/<stage dir>/ (replacing what was there): what a campaign needs to go on on another
    machine. A superseded stage that nothing reads is dropped from the campaign instead. An imitation stage is
    its campaign folder, kept whole (the stages that continue it included): its data are the planner's labels,
    the costliest thing a campaign holds."""
    recipe = R.load(name)
    saved = []
    for s in recipe.stages:
        if s.continues is not None:     # its rounds are in the folder of the stage it continues, saved with it
            continue
        drop = droppable(root, recipe, s)
        for run_dir in stage_dirs(root, recipe, s):
            dest = campaigns / name / run_dir.name
            if s.kind == "imitation" and _rounds(dest) > _rounds(run_dir):
                print(f"recipe {name}: {dest} holds more rounds than {run_dir} (rounds run into the campaign "
                      "itself): kept")
                saved.append(dest)
                continue
            # what the campaign folder holds beside the files copied from the run (a chain's evaluation report, its
            # figures) stays, even where the run has a file of that name
            copied = {f.name for f in run_dir.glob("*")} if s.kind == "imitation" else set(RUN_FILES)
            extra = {f.name: f.read_bytes() for f in dest.glob("*") if f.is_file() and f.name not in copied}
            if dest.exists():
                shutil.rmtree(dest)
            if drop:
                continue
            if s.kind == "imitation":
                shutil.copytree(run_dir, dest)
                _write(dest, extra)
                saved.append(dest)
                continue
            dest.mkdir(parents=True)
            for f in RUN_FILES:
                if (run_dir / f).exists():
                    shutil.copy2(run_dir / f, dest / f)
            if (dest / checkpoints.RUN_STATE).exists():
                _refer_to_campaign(dest / checkpoints.RUN_STATE, root, campaigns)
            kept = checkpoints.list_checkpoints(run_dir)
            ended = end_checkpoint(run_dir, s) if s.kind == "ppo" else None
            if ended is not None or kept:     # the checkpoint the stage ended at, else its newest
                chosen = ended or kept[-1]
                shutil.copytree(chosen, dest / checkpoints.CHECKPOINT_DIR / chosen.name)
            _write(dest, extra)
            saved.append(dest)
    return saved


def _write(folder: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        (folder / name).write_bytes(data)


def _refer_to_campaign(run_state: Path, runs: Path, campaigns: Path) -> None:
    """A kept run state's settings that name a file of a stage's run (runs/RECIPE/<stage>/…, absolute or
    repository-relative; this recipe's or another's: a start bank's policy, a teacher) name that stage's kept run
    instead (campaigns/RECIPE/<stage>, repository-relative): runs/ is not on another clone."""
    def point(value):
        if isinstance(value, dict):
            return {k: point(v) for k, v in value.items()}
        if isinstance(value, list):
            return [point(v) for v in value]
        path = checkpoints.repo_path(value).resolve() if isinstance(value, str) and value else None
        if path is not None and path.is_relative_to(runs.resolve()) and len(path.relative_to(runs.resolve()).parts) > 1:
            recipe, stage = path.relative_to(runs.resolve()).parts[:2]
            return checkpoints.repo_relative(campaigns / recipe / stage)
        return value
    state = json.loads(run_state.read_text())
    state = {k: point(v) if k in ("env_config", "ppo_config") else v for k, v in state.items()}
    run_state.write_text(json.dumps(state, indent=1, sort_keys=True, default=str) + "\n")


def droppable(root: Path, recipe: R.Recipe, stage: R.Stage) -> bool:
    """Whether a campaign drops `stage`: superseded and read by nothing (an imitation stage's data are kept)."""
    return stage.kind != "imitation" and superseded(root, recipe, stage) and not referenced(recipe, stage)


def restore_campaign(recipe: R.Recipe, stage: R.Stage, root: Path, campaigns: Path = CAMPAIGNS_ROOT) -> None:
    """A stage absent from `root` but kept in the campaign is copied back, so --resume goes on from it."""
    base = campaigns / recipe.name
    for src in sorted(base.glob(f"{stage.name}")) + sorted(base.glob(f"{stage.name}.*")):
        dest = root / recipe.name / src.name
        if not dest.exists():
            shutil.copytree(src, dest)
            print(f"recipe {recipe.name}: stage {src.name} restored from {src}")
