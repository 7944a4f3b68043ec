"""`python -m training recipe NAME`: runs a recipe's stages in order into RUNS_ROOT/NAME/<stage>, skipping the
ones already complete, and keeps a campaign across machines in training/campaigns/NAME/ (the newest
checkpoint, run state and curve of each stage; nothing else from runs/ is tracked).

    recipe --list                                  the recipes, their policies and stages
    recipe NAME [--stage S] [--resume] [--max-minutes M] [--backend cpu|mjx] [--ship]
    recipe NAME --save-campaign                    copy each stage's newest checkpoint, state, curve
    recipe NAME --toy --out DIR                    every stage at toy size (CI: no recipe rots)
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from common.artifact import read_artifact
from training.core import checkpoints
from training.core.backend import default_backend
from training.distill import dagger as distill
from training.distill.dagger import LEARNER_KEYS as DISTILL_KEYS
from training.distill.finetune import LEARNER_KEYS
from training.envs import starts
from training.envs.policy_files import CHECKPOINT_DIR
from training.export import untrained
from training.export.brax import ship_artifact, ship_chain
from training.imitation import campaign as imitation
from training.imitation.finetune import LEARNER_KEYS as IMITATION_KEYS
from training.ppo import migration, train
from training.recipes import base as R
from training.recipes.campaign import (  # noqa: F401  (save_campaign: also the runner's API)
    CAMPAIGNS_ROOT,
    RUNS_ROOT,
    restore_campaign,
    save_campaign,
)
from training.recipes.stages import (  # noqa: F401  (stage_complete, end_checkpoint: also the runner's API)
    DISTILL_STATE,
    TOY_END_AT_STEPS,
    TOY_PPO_STEPS,
    _json,
    _rounds,
    artifact_name,
    end_at,
    end_checkpoint,
    referenced,
    stage_artifact,
    stage_complete,
    stage_dirs,
    superseded,
)

TOY_BANK_STARTS = 4       # landing banks of a toy stage (their rollouts dominate a toy run otherwise)
# a toy imitation stage: its rounds (as many as the stage's, so that round numbers read the same), of this size
# a toy BC term reads every round: a toy best-of-K round labels nothing (no 0.2 s rise meets the gate)
TOY_ALL_ROUNDS = ("ppo.imitation.first_round",)
TOY_IMITATION = ("dagger.starts_per_round=2", "dagger.rollout_s=0.2", "dagger.eval_seeds=2",
                 "dagger.eval_seconds=0.2", "dagger.fit.steps=2", "dagger.fit.hidden_layer_sizes=[16, 16]",
                 "dagger.expert.policy_samples=2", "dagger.expert.plan_samples=2", "dagger.expert.horizon_s=0.2")


def describe() -> str:
    lines = []
    for name in R.names():
        r = R.load(name)
        stages = " → ".join(f"{s.name} ({s.kind}{', ' + format(s.steps, ',') if s.steps else ''})" for s in r.stages)
        lines.append(f"{name}: policies/{r.policy}/  {r.summary}\n    {stages}")
    return "\n".join(lines)


def _stage_of(init: str, recipe: R.Recipe) -> tuple[R.Recipe, R.Stage]:
    """The recipe and stage `init` names (a stage of `recipe`, or @RECIPE/STAGE)."""
    if init.startswith(R.REF_PREFIX):
        name, _, stage_name = init[1:].partition("/")
        recipe = R.load(name)
    else:
        stage_name = init
    return recipe, recipe.stage(stage_name)


def _run_dir(init: str, recipe: R.Recipe, root: Path) -> Path:
    """The newest run directory of `init` (a stage of `recipe`, or @RECIPE/STAGE)."""
    recipe, stage = _stage_of(init, recipe)
    dirs = stage_dirs(root, recipe, stage)
    if not dirs:
        raise FileNotFoundError(f"{init}: not run under {root}; run `python -m training recipe {recipe.name} "
                                f"--stage {stage.name}` first (with the same --out)")
    return dirs[-1]


def _init_path(init: str, recipe: R.Recipe, root: Path) -> Path:
    """What a stage starts from: the run directory of `init` (its newest checkpoint), the checkpoint it ended at
    (end_at), or, of an imitation campaign, its learner's artifact (a PPO fine-tune of the DAgger policy)."""
    run_dir = _run_dir(init, recipe, root)
    recipe, stage = _stage_of(init, recipe)
    if stage.kind == "imitation":
        return stage_artifact(run_dir, recipe, stage)
    if stage.kind == "ppo" and stage.end_at is not None:   # a distill stage stops at its end: its newest
        ended = end_checkpoint(run_dir, stage)
        if ended is None:
            raise FileNotFoundError(f"{init}: {run_dir} has no checkpoint at its end_at ({stage.end_at:,} env "
                                    f"steps) yet; run `python -m training recipe {recipe.name} --stage "
                                    f"{stage.name} --resume` first")
        return ended
    return run_dir


def ended_artifact(run_dir: Path, recipe: R.Recipe, stage: R.Stage) -> Path:
    """A PPO stage's artifact at the checkpoint it ended at: its run's export where that is of this checkpoint,
    else that checkpoint exported in its place (a run that went further, or a campaign's kept checkpoint)."""
    path = stage_artifact(run_dir, recipe, stage)
    ended = end_checkpoint(run_dir, stage) if stage.kind == "ppo" else None
    if ended is None:
        return path
    if not path.exists():    # a campaign restored without its export: the newest checkpoint's, for the manifest
        path = export_newest(run_dir)
    if path.exists() and int(read_artifact(path)[3]["provenance"]["steps"]) == int(ended.name):
        return path
    return train.export_checkpoint(run_dir, int(ended.name), artifact_name(recipe, stage), like=path)


def _policy_path(policy: str, recipe: R.Recipe, root: Path) -> Path:
    """The artifact of the stage `policy` names (at its end): what an imitation stage's rounds are rolled out
    by, or what a PPO stage with init_artifact starts from (which may also be a shipped artifact)."""
    if policy.startswith(R.SHIPPED_PREFIX):
        path = checkpoints.repo_path(policy)
        if not path.is_file():
            raise FileNotFoundError(f"{policy}: no such shipped artifact")
        return path
    run_dir = _run_dir(policy, recipe, root)
    recipe, stage = _stage_of(policy, recipe)
    return ended_artifact(run_dir, recipe, stage)


def export_newest(run_dir) -> Path:
    """A run's newest kept checkpoint → its export (run_dir/<name>.safetensors), as the run's end exports it: what a
    campaign restored on another machine (checkpoint and run state only) exports when a later stage reads it. The
    manifest's env fields come from the run's env without its start banks (they do not depend on them)."""
    run_dir = Path(run_dir)
    state = checkpoints.load_run_state(run_dir)
    ppo_cfg, env_cfg = migration.run_configs(state, str(run_dir / checkpoints.RUN_STATE))
    if "fallen" in env_cfg:
        env_cfg.fallen.update(bank_starts=1, side_weights=[1] * len(env_cfg.fallen.side_weights))
    for group in starts.SOURCES:   # the banked start sources off: building them rolls policies out
        if group.bank and group.group in env_cfg:
            env_cfg[group.group].prob = 0.0
    env_cfg.backend = "cpu"
    state = {**state, "ppo_config": ppo_cfg.to_dict(), "env_config": env_cfg.to_dict()}
    params = checkpoints.load_checkpoint(run_dir)
    return train.export_run(run_dir, train.make_env(migration.run_task(state, str(run_dir)), env_cfg), state, params,
                      state["preset"])


def resolve_ref(value, root: Path, shipped: bool = False):
    """A `@RECIPE/STAGE` reference → the artifact that stage exported into `root` (with `shipped`: that
    recipe's shipped policy instead, or before it ships the stage's kept campaign run); other values unchanged."""
    if not (isinstance(value, str) and value.startswith(R.REF_PREFIX)):
        return value
    name, _, stage_name = value[1:].partition("/")
    recipe = R.load(name)
    if shipped:
        policy = checkpoints.policy_dir(recipe.policy) / f"{recipe.policy}.safetensors"
        kept = CAMPAIGNS_ROOT / name / stage_name
        return str(kept if not policy.exists() and (kept / CHECKPOINT_DIR).is_dir() else policy)
    stage = recipe.stage(stage_name)
    dirs = stage_dirs(root, recipe, stage)
    path = ended_artifact(dirs[-1], recipe, stage) if dirs else None
    if path is not None and not path.exists() and stage.kind == "ppo" and stage_complete(root, recipe, stage):
        path = export_newest(dirs[-1])    # a campaign restored without its export
    if path is None or not path.exists():
        raise FileNotFoundError(f"{value}: no artifact under {root / name}; run `python -m training recipe {name} "
                                f"--stage {stage_name}` first (with the same --out)")
    return str(path)


def _overrides(config: dict, toy: bool) -> list[str]:
    """A stage's config diff as `key=value`; at toy size the PPO/DAgger sizes and rates stay the toy preset's
    (what the learner is, the fine-tunes' and DAgger's LEARNER_KEYS, stays the stage's) and the start banks are
    small."""
    if not toy:
        return [f"{k}={v!r}" for k, v in config.items()]
    banked = tuple(f"env.{s.group}" for s in starts.SOURCES if {"prob", "bank_starts"} <= set(s.functions()[0]()))
    out = [f"{k}={TOY_BANK_STARTS if k.endswith('.bank_starts') else v!r}" for k, v in config.items()
           if (k.startswith(LEARNER_KEYS + DISTILL_KEYS + IMITATION_KEYS) or not k.startswith(("ppo.", "bc.")))
           and k not in TOY_ALL_ROUNDS]
    for k, v in config.items():
        if k.endswith(".prob") and isinstance(v, float) and v > 0 and k[:-len(".prob")] in banked:
            out.append(f"{k[:-len('.prob')]}.bank_starts={TOY_BANK_STARTS}")
    return out


def run(name: str, *, stage: str | None = None, root: Path = RUNS_ROOT, resume: bool = False,
        max_minutes: float | None = None, backend: str | None = None, toy: bool = False, ship: bool = False,
        progress: bool = True) -> bool:
    """Run the recipe (or one stage of it); True when its last stage is complete."""
    recipe = R.load(name)
    provenance = {"name": name, "sha256": R.content_hash(name)}
    todo = recipe.stages if stage is None else (recipe.stage(stage),)
    t0 = time.monotonic()
    # every kept stage first: whether an earlier stage is superseded depends on the later ones (a toy run's
    # stages are its own)
    if resume and not toy:
        for s in recipe.stages:
            if not stage_dirs(root, recipe, s):
                restore_campaign(recipe, s, root)
    for s in todo:
        if stage_complete(root, recipe, s):
            print(f"recipe {name}: stage {s.name} complete ({stage_dirs(root, recipe, s)[-1]})")
            continue
        if stage is None and superseded(root, recipe, s):
            print(f"recipe {name}: stage {s.name} skipped (a later stage that starts from it is complete)")
            continue
        left = None if max_minutes is None else max_minutes - (time.monotonic() - t0) / 60.0
        if left is not None and left <= 0:
            break
        folder = recipe.campaign_stage(s).name if s.kind == "imitation" else s.name
        print(f"recipe {name}: stage {s.name} ({s.kind}) → {root / name / folder}", flush=True)
        _run_stage(recipe, s, root, resume=resume, max_minutes=left, backend=backend, toy=toy,
                   progress=progress, provenance={**provenance, "stage": s.name})
        if not stage_complete(root, recipe, s):
            print(f"recipe {name}: stage {s.name} stopped before its end; go on with --resume")
            return False
    final = recipe.stages[-1]
    complete = stage_complete(root, recipe, final)
    if complete and ship and recipe.chain:
        members = {role: ended_artifact(stage_dirs(root, recipe, recipe.stage(s))[-1], recipe, recipe.stage(s))
                   for role, s in recipe.chain.items()}
        folder = ship_chain(recipe.policy, members, recipe.handover, {"task": f"recipe {name}"})
        print(f"recipe {name}: shipped the chain {folder}")
    elif complete and ship:
        artifact = ended_artifact(stage_dirs(root, recipe, final)[-1], recipe, final)
        print(f"recipe {name}: shipped {ship_artifact(artifact, {'task': f'recipe {name}'})}")
    return complete


def _run_stage(recipe: R.Recipe, s: R.Stage, root: Path, *, resume: bool, max_minutes, backend, toy, progress,
               provenance: dict) -> None:
    dirs = stage_dirs(root, recipe, s)
    init = None if not s.init else _policy_path(s.init, recipe, root) if s.init_artifact else \
        _init_path(s.init, recipe, root)
    command = (f"python -m training recipe {recipe.name} --stage {s.name}"
               f"{' --toy' if toy else ''} (recipe sha256 {provenance['sha256'][:12]})")
    # a toy stage's landing banks roll the policies its config names, which must be trained experts (a toy
    # one never rises, rolls or falls as a bank needs): there a reference stands for that recipe's shipped policy
    # (or its kept campaign run before it ships)
    config = {k: resolve_ref(v, root, shipped=toy) for k, v in s.config.items()}
    if s.kind == "ppo":   # a PPO stage's teacher is its behaviour-cloning term's (training/distill/finetune.py)
        config.update({f"ppo.teacher.{k}": checkpoints.repo_relative(resolve_ref(v, root))
                       for k, v in s.teacher.items()})   # its run state then reads the same on any clone
    overrides = _overrides(config, toy)
    if toy and s.init_artifact and s.init.startswith(R.SHIPPED_PREFIX):   # a shipped learner keeps its size
        hidden = [w.shape[0] for w, _ in read_artifact(init)[0][:-1]]
        overrides.append(f"ppo.policy_hidden_layer_sizes={hidden!r}")
    name = artifact_name(recipe, s)
    if s.kind == "random_init":
        out = root / recipe.name / s.name
        out.mkdir(parents=True, exist_ok=True)
        untrained.main([str(out / f"{name}.safetensors")])
        return
    if s.kind == "imitation":
        _run_rounds(recipe, s, root, overrides + list(TOY_IMITATION if toy else ()), resume=resume,
                    max_minutes=max_minutes, toy=toy)
        return
    if s.kind == "ppo":
        out = root / recipe.name / s.name
        again = bool(dirs) and (out / checkpoints.RUN_STATE).exists()
        if again and not resume:
            raise FileExistsError(f"{out} holds an unfinished run of stage {s.name}: pass --resume to go on")
        preset = "toy" if toy else ("gpu" if (backend or default_backend()) == "mjx" else "cpu")
        steps, ends = s.steps, s.end_at
        if toy:
            steps, ends = TOY_END_AT_STEPS if s.end_at is not None else (TOY_PPO_STEPS, None)
        train.train(s.task, out, steps=steps, num_envs=None if toy else s.envs,
                    resume=again, max_minutes=max_minutes, overrides=() if again else overrides,
                    from_checkpoint=None if again else init, preset=preset, name=name,
                    command=command, progress=progress, backend=backend, recipe=provenance,
                    advance_at=s.advance_at, end_at=ends)
        if s.end_at is not None and stage_complete(root, recipe, s):
            ended_artifact(out, recipe, s)
        return
    teacher = {k: resolve_ref(v, root) for k, v in s.teacher.items()}
    phases = 0 if toy else int(s.steps)
    ends = None if toy or s.end_at is None else int(s.end_at)   # a toy run's few phases end at their last
    if dirs:   # a stopped DAgger stage goes on from its newest checkpoint into the next directory
        if not resume:
            raise FileExistsError(f"{dirs[-1]} holds an unfinished DAgger stage {s.name}: pass --resume to go on")
        start, done_phases = dirs[-1], _json(dirs[-1] / DISTILL_STATE).get("phases", 0)
        before = _json(init / DISTILL_STATE).get("phases", 0) if init else 0
        phases = max(phases - (int(done_phases) - int(before)), 1)
        ends = None if ends is None else ends - (int(done_phases) - int(before))
        evals = resumed_evals(phases, int(s.steps), int(s.config.get("bc.num_evals", 11)))
        if ends is not None:      # a checkpoint at the end phase too
            evals = phases // math.gcd(phases // evals, ends)
        overrides = [o for o in overrides if not o.startswith(("bc.dagger_steps=", "bc.num_evals="))]
        overrides += [f"bc.num_evals={evals + 1}"]
        out = root / recipe.name / f"{s.name}.{len(dirs) + 1}"
    else:
        start, out = init, root / recipe.name / s.name
    if phases:
        overrides = [o for o in overrides if not o.startswith("bc.dagger_steps=")] + [f"bc.dagger_steps={phases}"]
    distill.distill(teacher, out, task=s.task or distill.DEFAULT_TASK,
                    overrides=overrides, preset="toy" if toy else "gpu", num_envs=None if toy else s.envs,
                    command=command, progress=progress, max_minutes=max_minutes, name=name, backend=backend,
                    from_checkpoint=start, recipe=provenance, end_at=ends)


def resumed_evals(phases_left: int, steps: int, num_evals: int) -> int:
    """Evaluations (each a checkpoint, and where --max-minutes can stop) of a resumed DAgger stage's run over its
    phases_left: the most that divide them without checkpointing more often than the stage itself (steps /
    (num_evals − 1) phases apart)."""
    most = max(phases_left // max(steps // max(num_evals - 1, 1), 1), 1)
    return max(d for d in range(1, most + 1) if phases_left % d == 0)


def _run_rounds(recipe: R.Recipe, s: R.Stage, root: Path, overrides: list[str], *, resume: bool,
                max_minutes, toy: bool = False) -> None:
    """An imitation stage's rounds into its campaign folder. With a policy, a lying side or a roll, one call per
    round (each call's first round is the one `--policy` rolls out and `--lying` / `--rolled-by` starts: each of
    the stage's rounds is rolled out by that policy and refitted from it)."""
    folder = root / recipe.name / recipe.campaign_stage(s).name
    last = recipe.rounds_through(s)
    first = last - int(s.steps)
    if _rounds(folder) > first and not resume:
        raise FileExistsError(f"{folder} holds unfinished rounds of imitation stage {s.name}: pass --resume to go on")
    if _rounds(folder) < first:
        raise FileNotFoundError(f"{folder}: {_rounds(folder)} rounds, stage {s.name} continues from round {first}; "
                                f"run `python -m training recipe {recipe.name} --stage {s.continues}` first")
    overrides = [*overrides, f"dagger.rounds={last}"]
    policy = _policy_path(s.policy, recipe, root) if s.policy else None
    rolled_by = None
    if s.rolled_by:     # a toy roll never rolls over: a toy run starts where the kept or shipped roll hands over
        rolled_by = Path(resolve_ref(f"{R.REF_PREFIX}{recipe.name}/{s.rolled_by}", root, shipped=True)) if toy \
            else _policy_path(s.rolled_by, recipe, root)
    t0 = time.monotonic()
    each = policy is not None or bool(s.lying) or rolled_by is not None
    while _rounds(folder) < last:
        left = None if max_minutes is None else max_minutes - (time.monotonic() - t0) / 60.0
        if left is not None and left <= 0:
            return
        imitation.run(folder, overrides, rounds=_rounds(folder) + 1 if each else last, max_minutes=left,
                      policy=policy, lying=s.lying, rolled_by=rolled_by)
        if not each:
            return
