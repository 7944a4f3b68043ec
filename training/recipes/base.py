"""Named training recipes (training/recipes/<name>.py): a shipped policy's whole chain of stages, each a small
diff of its task's base config, so that `python -m training recipe NAME` makes the policy and its
provenance names the recipe and a hash of its content.

A stage is one PPO run (`train`), one DAgger run (`distill`: the student from expert policies), one DAgger
campaign with the rise planner as the expert (`imitation`: training/imitation/) or the seeded random init of
the untrained placeholder. `init` names the stage of the same recipe whose newest checkpoint (an imitation
campaign: its learner's artifact) it starts from (a fine-tune); `init` may also be `@RECIPE/STAGE`: that
stage of another recipe, run into the same runs root; with `init_artifact`, also a shipped artifact under policies/
(a fine-tune of what ships, whose own run is not kept). Policy
references in a stage (`teacher`, or config values) are paths under policies/ or `@RECIPE/STAGE`, the
artifact that stage exported.

A PPO stage with `end_at` ends at its kept checkpoint at that many env steps (its run may go further): that
checkpoint is what a later stage starts from and what the stage exports. A distill stage with `end_at` ends,
finished, at that DAgger phase (on the schedule of its `steps` phases). An imitation stage that `continues`
another appends its rounds to that stage's campaign folder (DAgger aggregates every round); with `policy`, each of
its rounds is rolled out by that stage's artifact (and refitted from it), with `lying`, from fallen starts lying
that way only, with `rolled_by`, from where that roll stage's artifact hands on-back and side falls over.
"""
from __future__ import annotations

import hashlib
import importlib
import pkgutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from common.events import KEYFRAME_STAGES, LYING_SIDES
from common.keyframe_chain import HANDOVERS

# a stage's teacher roles (training/distill/teacher.py's kinds: stitched, chain, kneeling)
TEACHERS = ({"getup", "joystick"}, set(KEYFRAME_STAGES), {*KEYFRAME_STAGES, "joystick"})

KINDS = ("ppo", "distill", "imitation", "random_init")
REF_PREFIX = "@"
SHIPPED_PREFIX = "policies/"


@dataclass(frozen=True)
class Stage:
    name: str
    kind: str = "ppo"
    task: str = ""                 # ppo: a task of training/envs (envs.TASKS); distill: the env (default unified)
    steps: int = 0                 # ppo: env steps of this stage; distill: DAgger phases; imitation: rounds
    # the stage to fine-tune from (this recipe's, or @RECIPE/STAGE; with init_artifact also a shipped artifact
    # policies/…); None = scratch
    init: str | None = None
    # the diff: {"env.x": v, "ppo.y": v, "bc.z": v}; imitation: {"dagger.x": v, "planner.y": v}
    config: Mapping[str, Any] = field(default_factory=dict)
    # distill: {"getup": ref, "joystick": ref} or {"roll": ref, "rise": ref, "stand": ref}; ppo: the same for a
    # behaviour-cloning term (ppo.teacher.*)
    teacher: Mapping[str, str] = field(default_factory=dict)
    envs: int | None = None        # parallel envs where the stage needs other than its preset's
    # ppo: (metric, value): the stage is complete at its first evaluation with the metric at or above the value
    # (backplay: the start moves back along the demonstrations once success from it has risen); steps cap it
    advance_at: tuple[str, float] | None = None
    # ppo: env steps of the kept checkpoint the stage ends at; distill: the phase it ends at (≤ steps: the run's
    # schedule stays that of `steps`)
    end_at: int | None = None
    # ppo: start from init's exported artifact (a fresh critic, the sampling std of ppo.init_noise_std) in place
    # of its checkpoint
    init_artifact: bool = False
    # imitation: the earlier imitation stage whose campaign folder this stage's rounds are appended to
    continues: str | None = None
    # imitation: the stage (this recipe's, or @RECIPE/STAGE) whose artifact rolls out each of this stage's rounds
    policy: str | None = None
    lying: str = ""                # imitation: this stage's rounds start only from fallen starts lying this way
    # imitation: the roll stage (getup_roll) whose hand-overs to the rise this stage's rounds start from
    rolled_by: str | None = None

    def references(self) -> list[str]:
        """Every `@RECIPE/STAGE` this stage reads."""
        values = [*self.teacher.values(), *self.config.values(), self.init, self.policy, self.rolled_by]
        return [v for v in values if isinstance(v, str) and v.startswith(REF_PREFIX)]


@dataclass(frozen=True)
class Recipe:
    name: str
    policy: str                    # the artifact's name: policies/<policy>/<policy>.safetensors
    summary: str
    stages: tuple[Stage, ...]
    # a keyframe chain (common/keyframe_chain.py) ships instead: role (roll, rise, stand) → the stage whose artifact
    # is that member, and the rise → stand hand-over by name; the policy is then the folder policies/<policy>/
    chain: Mapping[str, str] = field(default_factory=dict)
    handover: str = ""

    def __post_init__(self):
        names = [s.name for s in self.stages]
        if self.chain and (set(self.chain) != set(KEYFRAME_STAGES) or not set(self.chain.values()) <= set(names)
                           or self.handover not in HANDOVERS):
            raise ValueError(f"recipe {self.name}: a chain names a stage of this recipe for each of "
                             f"{', '.join(KEYFRAME_STAGES)} and a hand-over of {', '.join(HANDOVERS)}")
        if len(set(names)) != len(names):
            raise ValueError(f"recipe {self.name}: stage names repeat: {names}")
        for i, s in enumerate(self.stages):
            if s.kind not in KINDS:
                raise ValueError(f"recipe {self.name}, stage {s.name}: kind {s.kind!r} is not one of {KINDS}")
            shipped = s.init_artifact and s.init is not None and s.init.startswith(SHIPPED_PREFIX)
            if s.init is not None and not s.init.startswith(REF_PREFIX) and s.init not in names[:i] and not shipped:
                raise ValueError(f"recipe {self.name}, stage {s.name}: init {s.init!r} is not an earlier stage (or, "
                                 f"with init_artifact, a shipped artifact under {SHIPPED_PREFIX})")
            if s.advance_at is not None and (s.kind != "ppo" or len(s.advance_at) != 2):
                raise ValueError(f"recipe {self.name}, stage {s.name}: advance_at is a PPO stage's (metric, value)")
            if s.end_at is not None and (s.kind not in ("ppo", "distill") or not 0 < int(s.end_at) <= int(s.steps)):
                raise ValueError(f"recipe {self.name}, stage {s.name}: end_at is a PPO stage's checkpoint, in env "
                                 f"steps within its {s.steps:,}, or a distill stage's phase within its phases, "
                                 f"got {s.end_at!r}")
            if s.init_artifact and (s.kind != "ppo" or s.init is None):
                raise ValueError(f"recipe {self.name}, stage {s.name}: init_artifact is a PPO stage's with an init")
            self._check_rounds(s, names[:i])
            if (s.teacher or s.kind == "distill") and set(s.teacher) not in TEACHERS:
                raise ValueError(f"recipe {self.name}, stage {s.name}: a teacher is getup and joystick (the stitched "
                                 "teacher), roll, rise and stand (the keyframe chain) or roll, rise, stand and "
                                 "joystick (the chain below the waist switch, the joystick expert above)")

    def _check_rounds(self, s: Stage, earlier: list[str]) -> None:
        where = f"recipe {self.name}, stage {s.name}"
        if s.kind != "imitation":
            if s.continues or s.policy or s.lying or s.rolled_by:
                raise ValueError(f"{where}: continues, policy, lying and rolled_by are an imitation stage's")
            return
        if s.continues is not None and (s.continues not in earlier or self.stage(s.continues).kind != "imitation"):
            raise ValueError(f"{where}: continues {s.continues!r} is not an earlier imitation stage")
        for what, name in (("policy", s.policy), ("rolled_by", s.rolled_by)):
            if name is not None and not name.startswith(REF_PREFIX) and name not in earlier:
                raise ValueError(f"{where}: {what} {name!r} is not an earlier stage")
        if (s.policy or s.lying or s.rolled_by) and s.continues is None:
            raise ValueError(f"{where}: policy, lying and rolled_by take over rounds after the first: the stage "
                             "continues an earlier imitation stage's campaign")
        if s.lying and s.rolled_by:
            raise ValueError(f"{where}: lying and rolled_by are two sources of the rounds' starts: give one")
        if s.lying and s.lying not in LYING_SIDES:
            raise ValueError(f"{where}: lying must be one of {', '.join(LYING_SIDES)}, got {s.lying!r}")

    def campaign_stage(self, stage: Stage) -> Stage:
        """The imitation stage whose folder holds `stage`'s rounds (the first of the stages it continues)."""
        while stage.continues is not None:
            stage = self.stage(stage.continues)
        return stage

    def rounds_through(self, stage: Stage) -> int:
        """The rounds its campaign holds once the imitation stage `stage` is complete (its own and those of the
        stages before it that share the folder)."""
        folder = self.campaign_stage(stage)
        shared = [s for s in self.stages[:self.stages.index(stage) + 1]
                  if s.kind == "imitation" and self.campaign_stage(s) is folder]
        return sum(int(s.steps) for s in shared)

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
NOT_RECIPES = ("base", "campaign", "runner", "stages")   # the machinery beside the recipes


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
