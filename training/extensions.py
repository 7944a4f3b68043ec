"""Which PPOExtension (ppo_extension.py) a run gets, and what it starts from: RL from the imitation policy
(imitation/finetune.py) where its config or its start (a DAgger learner's artifact) asks for it, the student's
fine-tune (student_finetune.py) where its config or checkpoint does, else plain PPO."""
from __future__ import annotations

from training import checkpoints, student_finetune
from training.imitation import finetune
from training.ppo_extension import PPOExtension

is_artifact = finetune.is_artifact


def load_init(init):
    """What a run starts from: a PPO checkpoint's params, a DAgger learner's artifact (a dict), or None."""
    if not init:
        return None
    return finetune.read_learner(init) if is_artifact(init) else checkpoints.load_checkpoint(init)


def extension(ppo_cfg, restored) -> PPOExtension:
    if finetune.uses_imitation(ppo_cfg) or isinstance(restored, dict):
        return finetune.ImitationFinetune(ppo_cfg)
    return student_finetune.extension(ppo_cfg, restored)
