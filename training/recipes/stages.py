"""Where a recipe's stages stand in a runs root: their run directories, artifacts, the checkpoint a stage ends
at, whether it is complete or superseded. Read-only queries of what the runner (runner.py) writes."""
from __future__ import annotations

import json
from pathlib import Path

from training.core import checkpoints
from training.distill import dagger as distill
from training.imitation import config as imitation_config
from training.recipes import base as R

DISTILL_STATE = distill.STATE_FILE
TOY_PPO_STEPS = 80        # one toy PPO update: 8 envs × 5 unroll × 2 minibatches
# a toy stage with end_at: two updates' target, ended at the first (the end_at mechanism at toy size)
TOY_END_AT_STEPS = (2 * TOY_PPO_STEPS, TOY_PPO_STEPS)


def stage_dirs(root: Path, recipe: R.Recipe, stage: R.Stage) -> list[Path]:
    """The stage's run directories: <stage>, then <stage>.2, .3 … where a DAgger stage went on after a stop; an
    imitation stage that continues another: that stage's campaign folder."""
    name = recipe.campaign_stage(stage).name if stage.kind == "imitation" else stage.name
    base = root / recipe.name / name
    found = [base] if base.exists() else []
    k = 2
    while (root / recipe.name / f"{name}.{k}").exists():
        found.append(root / recipe.name / f"{name}.{k}")
        k += 1
    return found


def artifact_name(recipe: R.Recipe, stage: R.Stage) -> str:
    """The last stage's artifact is the recipe's policy; a chain's members, like every other stage, are named
    after their stage (the chain ships as a folder of them)."""
    return recipe.policy if stage is recipe.stages[-1] and not recipe.chain else f"{recipe.policy}_{stage.name}"


def stage_artifact(run_dir: Path, recipe: R.Recipe, stage: R.Stage) -> Path:
    """The artifact a stage's run directory exports (an imitation campaign's newest learner)."""
    if stage.kind == "imitation":
        return run_dir / imitation_config.ARTIFACT
    return run_dir / f"{artifact_name(recipe, stage)}.safetensors"


def end_at(stage: R.Stage, state: dict) -> int | None:
    """The env steps a PPO stage ends at (its end_at; a toy run's: TOY_END_AT_STEPS), None: at its target."""
    if stage.end_at is None:
        return None
    return TOY_END_AT_STEPS[1] if state.get("preset") == "toy" else int(stage.end_at)


def end_checkpoint(run_dir: Path, stage: R.Stage) -> Path | None:
    """The checkpoint a PPO stage with end_at ends at (None: not reached, or the stage has none)."""
    ends = end_at(stage, _json(run_dir / checkpoints.RUN_STATE))
    return None if ends is None else checkpoints.end_checkpoint(run_dir, ends)


def stage_complete(root: Path, recipe: R.Recipe, stage: R.Stage) -> bool:
    dirs = stage_dirs(root, recipe, stage)
    if not dirs:
        return False
    last = dirs[-1]
    if stage.kind == "random_init":
        return (last / f"{artifact_name(recipe, stage)}.safetensors").exists()
    if stage.kind == "distill":
        state = _json(last / DISTILL_STATE)
        return bool(state.get("finished")) and not state.get("stopped_by_max_minutes")
    if stage.kind == "imitation":    # its campaign holds the rounds through this stage's
        return _rounds(last) >= recipe.rounds_through(stage)
    state = _json(last / checkpoints.RUN_STATE)
    if stage.end_at is not None:
        return bool(state) and end_checkpoint(last, stage) is not None
    return bool(state) and (int(state["env_steps"]) >= int(state["target_steps"]) or "advanced" in state)


def superseded(root: Path, recipe: R.Recipe, stage: R.Stage) -> bool:
    """Whether a complete later stage of the recipe starts, through its chain of inits, from `stage` (a
    campaign may keep only the newest stage of a chain), and no imitation stage still to run rolls out by it."""
    for later in recipe.stages[recipe.stages.index(stage) + 1:]:
        chain, s = set(), later
        while s.init and not s.init.startswith((R.REF_PREFIX, R.SHIPPED_PREFIX)):
            chain.add(s.init)
            s = recipe.stage(s.init)
        if stage.name in chain and stage_complete(root, recipe, later):
            return not any(stage.name in (s.policy, s.rolled_by) and not stage_complete(root, recipe, s)
                           for s in recipe.stages if s.kind == "imitation")     # rounds it rolls out or starts
    return False


def referenced(recipe: R.Recipe, stage: R.Stage) -> bool:
    """Whether a stage's config or teacher in any recipe names `stage` (as @RECIPE/STAGE or by its campaign
    directory): a superseded stage that is still read stays in the campaign."""
    names = (f"{R.REF_PREFIX}{recipe.name}/{stage.name}", f"campaigns/{recipe.name}/{stage.name}")
    for other in map(R.load, R.names()):
        for s in other.stages:
            for value in (*s.config.values(), *s.teacher.values()):
                if isinstance(value, str) and any(value == n or value.endswith(n) for n in names):
                    return True
    return False


def _rounds(folder: Path) -> int:
    """The finished rounds of an imitation campaign folder (0: none, or no folder)."""
    return len(_json(folder / imitation_config.STATE).get("rounds", []))


def _json(path: Path) -> dict:
    return json.loads(path.read_text()) if path.exists() else {}
