"""MJX training envs for the T1 (JAX backend over mujoco_playground's MjxEnv).

    from training import envs
    envs.TASKS                      # ("joystick", "getup", "getup_kneel", "getup_roll", "getup_stand",
                                    #  "getup_baseline", "unified")
    cfg = envs.default_config("getup_kneel"); cfg.reward.scales.gate = 1.0
    env = envs.make("getup_kneel", cfg, config_overrides={"episode_length": 20})
    env.observation_size            # {"state": (n_actor,), "privileged_state": (n_critic,)}
    env.manifest_fields()           # artifact manifest fields (policies/ARTIFACT.md)
    envs.domain_randomize           # brax randomization_fn(mjx_model, rng) -> (model, in_axes)
    envs.fallen_states(num, seed)   # seeded settled fallen (qpos, qvel), numpy, cached

One file per task over base.py (the getup tasks over getup_base.py); rewards are small named functions
(joystick_rewards.py, getup_rewards.py) weighted by the config's `reward.scales`; configs are ml_collections
ConfigDicts in Playground's style, a task's a diff of its base's.
"""
from __future__ import annotations

import importlib
from typing import Callable

from ml_collections import config_dict

from training.envs.randomize import domain_randomize
from training.envs.starts.fallen import fallen_states

# task → (module under training/envs, env class). getup_roll turns a robot on its back face down (the chain's
# first stage), getup_kneel and getup_stand are the keyframe curriculum's
# stages 1 and 2, getup its gated full task; unified: the distillation env (walk, get pushed, fall, get up).
_REGISTRY: dict[str, tuple[str, str]] = {
    "joystick": ("joystick", "Joystick"), "getup": ("getup", "Getup"), "getup_kneel": ("getup_kneel", "GetupKneel"),
    "getup_roll": ("getup_roll", "GetupRoll"),
    "getup_stand": ("getup_stand", "GetupStand"), "getup_baseline": ("getup_baseline", "GetupBaseline"),
    "unified": ("unified", "Unified")}
TASKS: tuple[str, ...] = tuple(_REGISTRY)


def _module(task: str):
    if task not in _REGISTRY:
        raise ValueError(f"unknown task {task!r}; valid: {', '.join(TASKS)}")
    return importlib.import_module(f"training.envs.{_REGISTRY[task][0]}")


def default_config(task: str) -> config_dict.ConfigDict:
    """The task's default config (Playground-style ConfigDict; edit a copy, then pass it to make)."""
    return _module(task).default_config()


def env_class(task: str) -> Callable:
    return getattr(_module(task), _REGISTRY[task][1])


def make(task: str, config: config_dict.ConfigDict | None = None, config_overrides: dict | None = None):
    """Build the env for `task`. config defaults to default_config(task); config_overrides is a flat
    dict of dotted keys (e.g. {"episode_length": 20, "noise.level": 0.0}) applied on top. Unknown keys
    raise (ml_collections refuses to add fields to a locked config)."""
    cfg = default_config(task) if config is None else config
    if not isinstance(cfg, config_dict.ConfigDict):
        raise TypeError(f"config for {task!r} must be an ml_collections ConfigDict, got {type(cfg).__name__}")
    return env_class(task)(config=cfg, config_overrides=config_overrides, make_env=make)


__all__ = ["TASKS", "default_config", "make", "fallen_states", "domain_randomize", "env_class"]
