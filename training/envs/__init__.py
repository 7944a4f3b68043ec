"""MJX training envs for the T1 (JAX backend over mujoco_playground's MjxEnv).

    from training import envs
    envs.TASKS                      # ("joystick", "getup", "getup_baseline", "unified")
    cfg = envs.default_config("getup"); cfg.stage = "stage1"
    env = envs.make("getup", cfg, config_overrides={"episode_length": 20})
    env.observation_size            # {"state": (n_actor,), "privileged_state": (n_critic,)}
    env.manifest_fields()           # artifact manifest fields (policies/ARTIFACT.md)
    envs.domain_randomize           # brax randomization_fn(mjx_model, rng) -> (model, in_axes)
    envs.fallen_states(num, seed)   # seeded settled fallen (qpos, qvel), numpy, cached

One file per task over base.py; rewards are small named functions (joystick_rewards.py,
getup_rewards.py); configs are ml_collections ConfigDicts in Playground's style.
"""
from __future__ import annotations

from typing import Callable

from ml_collections import config_dict

from training.envs.starts.fallen import fallen_states
from training.envs.randomize import domain_randomize

# unified: the distillation env (walk, get pushed, fall, get up in one episode; envs/unified.py).
TASKS: tuple[str, ...] = ("joystick", "getup", "getup_baseline", "unified")


def _module(task: str):
    if task == "joystick":
        from training.envs import joystick as mod
    elif task == "getup":
        from training.envs import getup as mod
    elif task == "getup_baseline":
        from training.envs import getup_baseline as mod
    elif task == "unified":
        from training.envs import unified as mod
    else:
        raise ValueError(f"unknown task {task!r}; valid: {', '.join(TASKS)}")
    return mod


def default_config(task: str) -> config_dict.ConfigDict:
    """The task's default config (Playground-style ConfigDict; edit a copy, then pass it to make)."""
    return _module(task).default_config()


def env_class(task: str) -> Callable:
    mod = _module(task)
    return {"joystick": getattr(mod, "Joystick", None), "getup": getattr(mod, "Getup", None),
            "getup_baseline": getattr(mod, "GetupBaseline", None), "unified": getattr(mod, "Unified", None)}[task]


def make(task: str, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None):
    """Build the env for `task`. config defaults to default_config(task); config_overrides is a flat
    dict of dotted keys (e.g. {"episode_length": 20, "noise.level": 0.0}) applied on top. Unknown keys
    raise (ml_collections refuses to add fields to a locked config)."""
    cfg = default_config(task) if config is None else config
    if not isinstance(cfg, config_dict.ConfigDict):
        raise TypeError(f"config for {task!r} must be an ml_collections ConfigDict, got {type(cfg).__name__}")
    return env_class(task)(config=cfg, config_overrides=config_overrides, make_env=make)


__all__ = ["TASKS", "default_config", "make", "fallen_states", "domain_randomize", "env_class"]
