"""The start sources of the training envs, as a registry: each is one module that owns its config group
(`<config>()`: the share `prob`, `bank_starts`, `seed` and its own settings) and its bank (`<bank>(env, group)` →
(qpos, qvel), rolled once when the env is built). The task configs, the getup env and the recipe runner read
this list instead of naming banks; a new start source is a module and one line here.

The getup env's sources replace their `prob` of its fallen starts (shares summing to at most 1); the joystick
env's hand-over starts its own share of episodes (joystick.py)."""
from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StartSource:
    task: str              # the env whose config holds the group
    group: str             # its config group
    module: str            # the module that owns the group's config and bank functions
    config: str            # that module's function returning the group's defaults
    bank: str = ""         # that module's function (env, group) → (qpos, qvel); "" = the task's own code
    source_key: str = ""   # the group's field naming what makes the bank (a policy, a folder; "" = none)

    def functions(self):
        """(config function, bank function or None), imported on demand (the modules bring JAX along)."""
        mod = importlib.import_module(self.module)
        return getattr(mod, self.config), getattr(mod, self.bank) if self.bank else None


SOURCES: tuple[StartSource, ...] = (
    StartSource("getup", "knockdown_starts", "training.envs.handover", "knockdown_config", "knockdown_starts",
                "joystick_policy"),
    StartSource("getup", "demo_starts", "training.envs.demo_starts", "demo_config", "demo_starts", "folder"),
    StartSource("joystick", "handover", "training.envs.handover", "handover_config", "", "getup_policy"),
)


def sources(task: str) -> tuple[StartSource, ...]:
    return tuple(s for s in SOURCES if s.task == task)


def add_config_groups(cfg, task: str) -> None:
    """The task's start-source groups, at their defaults (off), into its config."""
    for s in sources(task):
        cfg[s.group] = s.functions()[0]()


def fallen_share_banks(env, cfg) -> list[tuple[float, tuple]]:
    """(share of the fallen starts, (qpos, qvel)) of the getup sources switched on in `cfg`, in registry order;
    the shares are checked before any bank is rolled."""
    wanted = []
    for s in sources("getup"):
        group = cfg[s.group]
        if not 0.0 <= group.prob <= 1.0:
            raise ValueError(f"{s.group}.prob must be in [0, 1], got {group.prob}")
        if group.prob > 0 and s.source_key and not group[s.source_key]:
            raise ValueError(f"{s.group}.prob > 0 needs {s.group}.{s.source_key}")
        if group.prob > 0:
            wanted.append((s, float(group.prob)))
    if sum(p for _, p in wanted) > 1.0 + 1e-9:
        raise ValueError("the start banks' shares must sum to at most 1, got "
                         f"{' + '.join(f'{s.group}.prob {p}' for s, p in wanted)}")
    return [(p, s.functions()[1](env, cfg[s.group])) for s, p in wanted]


def frozen_bank(pick, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A bank's (qpos, qvel) rows `pick` (a mask or indices), float32 and read-only (banks are cached and shared)."""
    bank = qpos[pick].astype(np.float32), qvel[pick].astype(np.float32)
    for array in bank:
        array.flags.writeable = False
    return bank
