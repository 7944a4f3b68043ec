"""What a PPO run may add to brax's PPO, as one narrow interface: its first params, the env wrapper brax trains
through, fields of the run state and an extra loss term. The trainer (ppo/train.py) knows only this; plain PPO is the
base class, the student's fine-tune (distill/finetune.py) and RL from the imitation policy (imitation/finetune.py) its
extensions."""
from __future__ import annotations

import contextlib
import functools

from mujoco_playground import wrapper


class PPOExtension:
    """Plain PPO: every hook leaves brax's run as it is."""

    def initial_params(self, restored, env=None):
        """A new run's first params from what it starts --from (None: brax initialises them); env: the task
        (its observation sizes)."""
        del env
        return restored

    def state_fields(self, params) -> dict:
        """Fields the run state keeps from the start (read back by loss_term on every resume)."""
        del params
        return {}

    def wrap_env_fn(self, env, full_reset: bool):
        """brax's wrap_env_fn: Playground's training wrapper."""
        del env
        return functools.partial(wrapper.wrap_for_brax_training, full_reset=full_reset)

    def loss_term(self, env, state: dict):
        """A context manager in which brax's PPO loss carries the extension's term."""
        del env, state
        return contextlib.nullcontext()
