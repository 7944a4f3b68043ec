"""Every way a training or evaluation episode can start, one module each in this folder, and their registry.

A start source's module owns its config group (`<config>()`: its defaults, off where it is optional) and, where
it replaces a share of a getup task's fallen starts, its bank (`<bank>(env, group)` → (qpos, qvel), rolled once
when the env is built). The task configs, the getup tasks and the recipe runner read SOURCES instead of naming
them; a new start source is a module and one line here. The evaluation's mid-fall starts (`evaluate --starts`)
are LANDINGS: each a module's bank of where the joystick expert, pushed or walked into a wall, hands over.

  fallen.py         seeded fallen states after the runtime's PREPARE ramp (every getup task's fallen starts)
  kneeling_path.py  the stand task's reverse curriculum along standing → half kneel → kneel
  demos.py          states along the planner's rises to the kneel (the kneel task's backplay; the full task's
                    distillation reads them too)
  rolled.py         where the keyframe chain's roll hands over to the face-down rise (the kneel task's)
  rise_kneels.py    where the chain's rise hands over to the stand, at the kneel band or §4.8's gate (the stand task's)
  fell_back.py      where the chain's rise has just failed an attempt (the kneel task's: try again)
  knockdown.py      the joystick expert knocked over by a velocity push, mid-fall
  push.py           the loop's push test (a torso impulse), mid-fall; the unified env's torso shove
  wall_approach.py  the low-wall course's approaches, and where the joystick expert falls over a wall
  handover.py       the getup expert's rise at the waist switch (the joystick env's hand-over starts)
  policy_rollout.py where a policy's rollouts first meet a hand-over condition (handover's and rolled's banks)
  landings.py       the joystick rollouts to a fall that knockdown, push and wall_approach share
  bank.py           what every bank shares: read-only float32 rows, a robot's state moved about the floor
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass


@dataclass(frozen=True)
class StartSource:
    tasks: tuple[str, ...]   # the envs whose config holds the group
    group: str               # its config group
    module: str              # the module that owns the group's config and bank functions
    config: str              # that module's function returning the group's defaults
    bank: str = ""           # that module's function (env, group) → (qpos, qvel); "" = the task's own code
    source_key: str = ""     # the group's field naming what makes the bank (a policy, a folder; "" = none)

    def functions(self):
        """(config function, bank function or None), imported on demand (the modules bring JAX along)."""
        mod = importlib.import_module(self.module)
        return getattr(mod, self.config), getattr(mod, self.bank) if self.bank else None


GETUP_TASKS = ("getup", "getup_kneel", "getup_roll", "getup_stand", "getup_baseline")
SOURCES: tuple[StartSource, ...] = (
    StartSource((*GETUP_TASKS, "unified"), "fallen", "training.envs.starts.fallen", "fallen_config"),
    StartSource(("getup_stand",), "reverse_curriculum", "training.envs.starts.kneeling_path", "path_config"),
    StartSource(("getup",), "knockdown_starts", "training.envs.starts.knockdown", "knockdown_config",
                "knockdown_starts", "joystick_policy"),
    StartSource(("getup_kneel", "getup"), "demo_starts", "training.envs.starts.demos", "demo_config", "demo_starts",
                "folder"),
    StartSource(("getup_kneel",), "rolled_starts", "training.envs.starts.rolled", "rolled_config", "rolled_starts",
                "roll_policy"),
    StartSource(("getup_kneel",), "fell_back", "training.envs.starts.fell_back", "fell_back_config",
                "fell_back_starts", "rise_policy"),
    StartSource(("getup_stand",), "rise_kneels", "training.envs.starts.rise_kneels", "rise_kneels_config", "",
                "rise_policy"),
    StartSource(("joystick",), "handover", "training.envs.starts.handover", "handover_config", "", "getup_policy"),
    StartSource(("unified",), "walls", "training.envs.starts.wall_approach", "walls_config"),
)

# evaluate --starts KIND: module whose `landing_bank(make_env, env, joystick_policy, num_starts, seed)` gives
# (qpos, qvel) where that joystick policy hands over to the getup expert mid-fall, for the getup `env` evaluated
LANDINGS: dict[str, str] = {"knockdown": "training.envs.starts.knockdown", "push": "training.envs.starts.push",
                            "wall": "training.envs.starts.wall_approach"}


def sources(task: str) -> tuple[StartSource, ...]:
    return tuple(s for s in SOURCES if task in s.tasks)


def add_config_groups(cfg, task: str) -> None:
    """The task's start-source groups, at their defaults (optional sources off), into its config."""
    for s in sources(task):
        cfg[s.group] = s.functions()[0]()


def fallen_share_banks(env, cfg) -> list[tuple[float, tuple]]:
    """(share of the fallen starts, (qpos, qvel)) of the banked sources whose group `cfg` holds, switched on, in
    registry order; the shares are checked before any bank is rolled."""
    wanted = []
    for s in SOURCES:
        if not s.bank or s.group not in cfg:
            continue
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


def landing_bank(kind: str):
    """The bank function of evaluation start `kind` (LANDINGS), imported on demand (it brings JAX along)."""
    if kind not in LANDINGS:
        raise ValueError(f"mid-fall start {kind!r}: one of {', '.join(LANDINGS)}")
    return importlib.import_module(LANDINGS[kind]).landing_bank
