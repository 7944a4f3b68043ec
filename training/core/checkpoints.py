"""Run directories, checkpoints and provenance records.

A run directory (`--out DIR`) holds:
    run_state.json        task, configs, target and done env steps, list of checkpoints, command history
    checkpoints/<step>/   orbax checkpoints written by brax's `training.checkpoint.save` (params tuple:
                          normalizer, policy[, value]) with the network config beside them
    metrics.csv, tensorboard/, learning_curve.png     (training/core/curves.py)
    <name>.safetensors    the exported policy (policies/ARTIFACT.md)

`--resume` reads run_state.json, restores the newest checkpoint and continues the env-step count from
it. brax's ppo.train restores parameters and the observation normaliser but not the Adam moments, so a
resumed run re-warms its optimiser (a few updates; documented in training/README.md).
"""
from __future__ import annotations

import json
import os
import shutil
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import jax
from brax.training import checkpoint as brax_checkpoint

# the reading side of the layout, below the envs (their start banks read policies too); part of this module's API
from training.envs.policy_files import (
    CHECKPOINT_DIR,  # noqa: F401
    RUN_STATE,  # noqa: F401
    list_checkpoints,  # noqa: F401
    load_checkpoint,  # noqa: F401
    resolve_checkpoint,  # noqa: F401
)

REPO_ROOT = Path(__file__).resolve().parents[2]
KEEP_CHECKPOINTS = 3  # older ones are deleted: each T1 PPO checkpoint is a few MB, GPU disks are small
STEP_DIGITS = 12      # brax names checkpoint folders f"{step:012d}"


def repo_relative(path) -> str:
    """How run states and reports name a file: repository-relative inside the repository (it then reads the
    same on any clone), else absolute."""
    path = Path(path).resolve()
    return str(path.relative_to(REPO_ROOT) if path.is_relative_to(REPO_ROOT) else path)


def repo_path(name) -> Path:
    """A name of repo_relative's (or a repository-relative setting) as a path on this clone."""
    path = Path(name)
    return path if path.is_absolute() else REPO_ROOT / path


# ---------------------------------------------------------------- jax
def jax_setup() -> None:
    """(1) A persistent compilation cache (T1_JAX_CACHE, default build/jax_cache): every ppo.train /
    bc.train call builds fresh closures, so without it each --resume call (and each test) recompiles
    the MJX step for minutes. (2) brax 0.14.2 calls jax.device_put_replicated, removed from jax's
    namespace in 0.10 (the function itself is still in jax._src.api); put it back."""
    cache = os.environ.get("T1_JAX_CACHE", str(REPO_ROOT / "build" / "jax_cache"))
    if cache and jax.config.jax_compilation_cache_dir is None:
        jax.config.update("jax_compilation_cache_dir", cache)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    try:
        jax.device_put_replicated  # noqa: B018 (probe)
    except AttributeError:
        from jax._src import api  # only on a jax without it (its private home; the public name is gone)
        jax.device_put_replicated = api.device_put_replicated


# ---------------------------------------------------------------- run state
def load_run_state(run_dir) -> dict[str, Any]:
    path = Path(run_dir) / RUN_STATE
    if not path.exists():
        raise FileNotFoundError(f"--resume: {path} does not exist (no run to resume in {run_dir})")
    return json.loads(path.read_text())


def save_run_state(run_dir, state: dict[str, Any]) -> None:
    path = Path(run_dir) / RUN_STATE
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(state, indent=1, sort_keys=True, default=str) + "\n")
    tmp.replace(path)  # atomic: a run killed mid-write keeps the previous state


# ---------------------------------------------------------------- checkpoints (orbax via brax)
def save_checkpoint(run_dir, env_steps: int, params, network_config, end_at: int | None = None) -> Path:
    """Write params at `env_steps` (total over all resumes) and prune to the newest KEEP_CHECKPOINTS; the
    checkpoint a run ends at (end_checkpoint of `end_at`) is kept however far the run goes."""
    root = Path(run_dir) / CHECKPOINT_DIR
    brax_checkpoint.save(root, int(env_steps), tuple(params), network_config, "network_config.json")
    keep = end_checkpoint(run_dir, end_at) if end_at is not None else None
    for old in list_checkpoints(run_dir)[:-KEEP_CHECKPOINTS]:
        if old != keep:
            shutil.rmtree(old, ignore_errors=True)
    return checkpoint_path(run_dir, env_steps)


def end_checkpoint(run_dir, end_at: int) -> Path | None:
    """The checkpoint a run ends at: its first kept one at or after `end_at` env steps (a run's checkpoints fall
    on its epochs, whole PPO updates), or None before it got there."""
    return next((p for p in list_checkpoints(run_dir) if int(p.name) >= int(end_at)), None)


def checkpoint_path(run_dir, count: int) -> Path:
    """The folder of the checkpoint at `count` (PPO: env steps; DAgger: phases), as brax names it."""
    return Path(run_dir) / CHECKPOINT_DIR / f"{int(count):0{STEP_DIGITS}d}"


def kept_checkpoint(run_dir, count: int, what: str) -> Path:
    """checkpoint_path, or an error that names the counts the run still keeps (`what`: e.g. "phase 3")."""
    path = checkpoint_path(run_dir, count)
    if not path.is_dir():
        found = [int(p.name) for p in list_checkpoints(run_dir)]
        raise FileNotFoundError(f"{path}: no checkpoint at {what} (the run keeps {found})")
    return path


def checkpoint_steps(path) -> int:
    return int(resolve_checkpoint(path).name)


# ---------------------------------------------------------------- provenance
def git_commit() -> str:
    """HEAD's commit read from .git (no git process: the checkout may be shared and busy)."""
    git = REPO_ROOT / ".git"
    try:
        if git.is_file():  # worktree: "gitdir: PATH"
            git = (REPO_ROOT / git.read_text().split(":", 1)[1].strip()).resolve()
        head = (git / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head[:12]
        ref = head.split(" ", 1)[1]
        ref_file = git / ref
        if ref_file.exists():
            return ref_file.read_text().strip()[:12]
        packed = git / "packed-refs"
        for line in packed.read_text().splitlines() if packed.exists() else []:
            if line.endswith(" " + ref):
                return line.split()[0][:12]
        common = git / "commondir"
        if common.exists():
            common_dir = (git / common.read_text().strip()).resolve()
            if (common_dir / ref).exists():
                return (common_dir / ref).read_text().strip()[:12]
    except OSError:
        pass
    return "unknown"


def device_description() -> str:
    device = jax.devices()[0]
    return f"{device.platform}:{getattr(device, 'device_kind', 'unknown')} x{jax.device_count()}"


def utc_now() -> str:
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


# ---------------------------------------------------------------- policies/<name>/CARD.md
POLICIES_ROOT = REPO_ROOT / "policies"
CARD = "CARD.md"
PROVENANCE_COLUMNS = ("date", "artifact", "name", "task", "trained", "env steps", "minutes", "env-steps/s",
                      "device", "git commit", "content hash", "command", "evaluation")
# A card the first --ship of a policy creates: the sections every card has, in a card's order (what it is, how
# to run it, what it measured, then its lineage), to be filled in from the evaluations before the policy counts
# as shipped; --ship appends its provenance rows at the end.
CARD_TEMPLATE = (
    "# {name}\n\nWhat it is: (to write)\n\n## Run it\n(to write)\n\n## Measured\n(no figure yet: "
    "`python -m training evaluate` and the loop's `make eval-*`)\n\n## Misses / known limits\n(to write)\n\n"
    "## How it was made\nThe provenance rows below (recipe, commit, command).\n\n## Provenance\n")


def policy_dir(name: str, root=POLICIES_ROOT) -> Path:
    return Path(root) / name


def _cell(value) -> str:
    return str(value).replace("|", "\\|").replace("\n", " ")


def provenance_row(fields: dict[str, Any]) -> str:
    missing = [c for c in PROVENANCE_COLUMNS if c not in fields]
    if missing:
        raise ValueError(f"provenance row: missing column(s) {missing}")
    return "| " + " | ".join(_cell(fields[c]) for c in PROVENANCE_COLUMNS) + " |\n"


def append_provenance_row(fields: dict[str, Any], table) -> Path:
    """Append one row to a card's provenance table; create the card (CARD_TEMPLATE) when the file is new, the
    table (header, column line) when the card has none."""
    table = Path(table)
    text = table.read_text() if table.exists() else ""
    head_line = "| " + " | ".join(PROVENANCE_COLUMNS) + " |\n"
    if head_line not in text:
        if not text:
            text = CARD_TEMPLATE.format(name=fields["name"])
        elif not text.endswith("\n"):
            text += "\n"
        text += head_line + "|" + "---|" * len(PROVENANCE_COLUMNS) + "\n"
    table.write_text(text + provenance_row(fields))
    return table
