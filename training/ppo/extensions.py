"""Which PPOExtension (core/extension.py) a run gets, and what it starts from: RL from the imitation policy
(imitation/finetune.py) where its config or its start (a DAgger learner's artifact) asks for it, the student's
fine-tune (distill/finetune.py) where its config or checkpoint does, else plain PPO."""
from __future__ import annotations

from pathlib import Path

from training.core import checkpoints
from training.core.extension import PPOExtension
from training.distill import finetune as student_finetune
from training.imitation import finetune

is_artifact = finetune.is_artifact
pin_campaign = finetune.pin_campaign


def init_path(path: Path) -> str:
    """How a run state names what it starts from: repository-relative inside the repository (a campaign's run
    state then resumes on any clone; the imitation fine-tune reads its planner data beside it), else absolute."""
    return checkpoints.repo_relative(path)


def resolved(init: str) -> Path:
    """A run state's init as a path (repository-relative ones against this clone)."""
    return checkpoints.repo_path(init)


def load_init(init):
    """What a run starts from: a PPO checkpoint's params, a DAgger learner's artifact (a dict), or None."""
    if not init:
        return None
    path = resolved(init)
    return finetune.read_learner(path) if is_artifact(path) else checkpoints.load_checkpoint(path)


def extension(ppo_cfg, restored) -> PPOExtension:
    if finetune.uses_imitation(ppo_cfg) or isinstance(restored, dict):
        return finetune.ImitationFinetune(ppo_cfg)
    return student_finetune.extension(ppo_cfg, restored)
