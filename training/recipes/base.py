"""Named training recipes (training/recipes/<name>.py): a shipped policy's whole chain of stages, each a small
diff of its task's base config, so that `python -m training recipe NAME` makes the policy and its
provenance names the recipe and a hash of its content.

A stage is one PPO run (`train`), one DAgger run (`distill`: the student from expert policies), one DAgger
campaign with the rise planner as the expert (`imitation`: training/imitation/) or the seeded random init of
the untrained placeholder. `init` names the stage of the same recipe whose newest checkpoint (an imitation
campaign: its learner's artifact) it starts from (a fine-tune); `init` may also be `@RECIPE/STAGE`: that
stage of another recipe, run into the same runs root. Policy
references in a stage (`teacher`, or config values) are paths under policies/ or `@RECIPE/STAGE`, the
artifact that stage exported.
"""
from __future__ import annotations

import hashlib
import importlib
import pkgutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

KINDS = ("ppo", "distill", "imitation", "random_init")
REF_PREFIX = "@"


@dataclass(frozen=True)
class Stage:
    name: str
    kind: str = "ppo"
    task: str = ""                 # ppo: a task of training/envs (envs.TASKS); distill: the env (default unified)
    steps: int = 0                 # ppo: env steps of this stage; distill: DAgger phases; imitation: rounds
    init: str | None = None        # the stage to fine-tune from (this recipe's, or @RECIPE/STAGE); None = scratch
    # the diff: {"env.x": v, "ppo.y": v, "bc.z": v}; imitation: {"dagger.x": v, "planner.y": v}
    config: Mapping[str, Any] = field(default_factory=dict)
    # distill: {"getup": ref, "joystick": ref} or {"roll": ref, "rise": ref, "stand": ref}; ppo: the same for a
    # behaviour-cloning term (ppo.teacher.*)
    teacher: Mapping[str, str] = field(default_factory=dict)
    envs: int | None = None        # parallel envs where the stage needs other than its preset's
    # ppo: (metric, value): the stage is complete at its first evaluation with the metric at or above the value
    # (backplay: the start moves back along the demonstrations once success from it has risen); steps cap it
    advance_at: tuple[str, float] | None = None

    def references(self) -> list[str]:
        """Every `@RECIPE/STAGE` this stage reads."""
        values = [*self.teacher.values(), *self.config.values(), self.init]
        return [v for v in values if isinstance(v, str) and v.startswith(REF_PREFIX)]


@dataclass(frozen=True)
class Recipe:
    name: str
    policy: str                    # the artifact's name: policies/<policy>/<policy>.safetensors
    summary: str
    stages: tuple[Stage, ...]

    def __post_init__(self):
        names = [s.name for s in self.stages]
        if len(set(names)) != len(names):
            raise ValueError(f"recipe {self.name}: stage names repeat: {names}")
        for i, s in enumerate(self.stages):
            if s.kind not in KINDS:
                raise ValueError(f"recipe {self.name}, stage {s.name}: kind {s.kind!r} is not one of {KINDS}")
            if s.init is not None and not s.init.startswith(REF_PREFIX) and s.init not in names[:i]:
                raise ValueError(f"recipe {self.name}, stage {s.name}: init {s.init!r} is not an earlier stage")
            if s.advance_at is not None and (s.kind != "ppo" or len(s.advance_at) != 2):
                raise ValueError(f"recipe {self.name}, stage {s.name}: advance_at is a PPO stage's (metric, value)")
            stitched, chain = {"getup", "joystick"}, {"roll", "rise", "stand"}
            if s.kind == "distill" and set(s.teacher) not in (stitched, chain):
                raise ValueError(f"recipe {self.name}, stage {s.name}: a distill stage's teacher is getup and "
                                 "joystick (the stitched teacher) or roll, rise and stand (the keyframe chain)")
            if s.kind != "distill" and s.teacher and set(s.teacher) not in (stitched, chain):
                raise ValueError(f"recipe {self.name}, stage {s.name}: a teacher is getup and joystick or roll, rise "
                                 "and stand")

    def stage(self, name: str) -> Stage:
        for s in self.stages:
            if s.name == name:
                return s
        raise ValueError(f"recipe {self.name} has no stage {name!r}; stages: "
                         f"{', '.join(s.name for s in self.stages)}")

    def depends_on(self) -> set[str]:
        """The other recipes whose stage artifacts this one reads (`@RECIPE/STAGE`)."""
        return {ref[1:].split("/")[0] for s in self.stages for ref in s.references()} - {self.name}


def _module_file(name: str) -> Path:
    return Path(importlib.import_module(f"training.recipes.{name}").__file__)


# the recipes package's modules that are no recipe: this file and the runner
NOT_RECIPES = ("base", "runner")


def names() -> list[str]:
    """The recipes: every module of training/recipes/ but NOT_RECIPES."""
    return sorted(m.name for m in pkgutil.iter_modules([str(Path(__file__).parent)])
                  if not m.name.startswith("_") and m.name not in NOT_RECIPES)


def load(name: str) -> Recipe:
    if name not in names():
        raise ValueError(f"unknown recipe {name!r}; recipes: {', '.join(names())}")
    recipe = importlib.import_module(f"training.recipes.{name}").RECIPE
    if recipe.name != name:
        raise ValueError(f"training/recipes/{name}.py defines recipe {recipe.name!r}, not {name!r}")
    return recipe


def content_hash(name: str) -> str:
    """sha256 of the recipe's file: what provenance records beside the recipe's name."""
    return hashlib.sha256(_module_file(name).read_bytes()).hexdigest()


def in_dependency_order(recipe_names) -> list[str]:
    """The recipes ordered so that each comes after those it reads stage artifacts from."""
    pending, done = list(recipe_names), []
    while pending:
        ready = [n for n in pending if load(n).depends_on() & set(recipe_names) <= set(done)]
        if not ready:
            raise ValueError(f"recipes {pending} read each other's stages in a circle")
        done.extend(ready)
        pending = [n for n in pending if n not in ready]
    return done
