"""A saved run's task and configs brought to today's schema, in one place: resume and checkpoint export read a
run only through `run_task` and `run_configs`, so the envs and networks see today's keys and defend against no
older run.

* a key the run predates gets today's default (`envs.default_config(task)`, `configs.ppo_config(task, preset)`):
  every knob was added with the default that keeps the behaviour before it;
* RENAMED maps a key's old dotted path to today's (with a conversion where its meaning's sign changed);
* REMOVED lists the knobs of finished experiments (training/LESSONS.md names the removing commit). A run that set
  one to its neutral value (what the code did without the experiment) drops it silently: it trained as today's
  code trains. Any other value is refused with the key's name: the code that read it is gone, so the run cannot
  go on as it was made;
* a getup run from before each getup stage had a task of its own (task "getup" with env_config "stage") becomes
  a run of that stage's task (GETUP_STAGES); SPLIT moves its stage's keys to that task's and drops the keys its
  stage never read (UNUSED) or refuses them as REMOVED does;
* a key in none of these (a typo, a newer schema) is refused as well.
"""
from __future__ import annotations

from typing import Any, Callable, Mapping

from ml_collections import config_dict

from training import envs
from training.ppo.configs import ppo_config


def _cost_scale(weight):
    """A cost's weight (subtracted) → its term's reward scale (added): the same reward."""
    return -weight if weight else 0.0


# old dotted path → today's (or (today's, conversion of the value)), per config ("env", "ppo")
RENAMED: dict[str, dict[str, str | tuple[str, Callable]]] = {
    "env": {"fallen_bank_size": "fallen.bank_starts", "fallen_seed": "fallen.seed",
            "fallen_prepare_s": "fallen.prepare_s", "energy_weight": ("reward.scales.energy", _cost_scale),
            "reward.getup.energy_weight": ("reward.getup.scales.energy", _cost_scale)},
    "ppo": {}}


class _Unused:
    """A removed key the run's task never read: dropped whatever its value."""

    def __repr__(self) -> str:
        return "unused"


UNUSED = _Unused()

# removed dotted path → its neutral value: a scalar the saved value must equal, or, for a group, the
# {field: value} that switches the group off (its other fields are then irrelevant)
REMOVED: dict[str, dict[str, Any]] = {
    "env": {"upright_policy": "", "rise_pace": {"weight": 0.0}, "gravity_scale": 1.0, "wall_starts": {"prob": 0.0},
            "push_starts": {"prob": 0.0}, "handover.push_prob": 0.0, "failed_rise": {"cost": 0.0},
            "handover.knockdown_prob": 0.0, "handover.joystick_policy": "", "handover.zero_command_prob": 0.0,
            "push.torso_shove_prob": 0.0, "harness": {"stiffness_n_per_m": 0.0}, "rise_starts": {"prob": 0.0},
            "collapse_starts": {"prob": 0.0}, "prone_starts": {"prob": 0.0},
            # the kneel task's sag end and demonstration tracking term: no recipe sets them
            "drop_below_gate_m": 0.0, "reward.scales.track": 0.0, "tracking": UNUSED},
    "ppo": {}}

# getup runs before the split: env_config["stage"] (default "full") → today's task
GETUP_STAGES = {"stage1": "getup_kneel", "stage2": "getup_stand", "full": "getup"}
_STAGE1_KEYS = ("stage1_start_probs", "stage1_gate_reward", "stage1_upright_reward", "stage1_drop_below_m")
_STAGE2_KEYS = ("stage2_start_probs", "stage2_fall_trunk_height_m", "stage2_fall_up_z")
# per old stage: {"renamed": old → today's path, "removed": path → neutral value or UNUSED}. gate_latches: the
# kneel task's gate latches, the others' is per step (LESSONS.md, "Knobs and modules removed")
SPLIT: dict[str, dict[str, dict[str, Any]]] = {
    "stage1": {"renamed": {"stage1_start_probs": "start_probs", "stage1_gate_reward": "reward.scales.gate",
                           "stage1_upright_reward": "reward.scales.upright"},
               "removed": {"stage": UNUSED, "stage1_drop_below_m": 0.0, "start_probs": UNUSED,
                           **dict.fromkeys(_STAGE2_KEYS, UNUSED), "reverse_curriculum": UNUSED, "gate_latches": True,
                           "knockdown_starts": {"prob": 0.0}}},
    "stage2": {"renamed": {"stage2_start_probs": "start_probs", "stage2_fall_trunk_height_m": "fall_trunk_height_m",
                           "stage2_fall_up_z": "fall_up_z"},
               "removed": {"stage": UNUSED, "start_probs": UNUSED, **dict.fromkeys(_STAGE1_KEYS, UNUSED),
                           "gate_latches": False, "knockdown_starts": {"prob": 0.0}, "demo_starts": {"prob": 0.0}}},
    # also today's getup runs (no env.stage); reward.scales.upright: the kneel task's slope, once the full task's too
    "full": {"renamed": {},
             "removed": {"stage": UNUSED, **dict.fromkeys(_STAGE1_KEYS + _STAGE2_KEYS, UNUSED),
                         "reverse_curriculum": UNUSED, "gate_latches": False, "demo_starts": {"prob": 0.0},
                         "reward.scales.upright": 0.0}},
}


class MigrationError(ValueError):
    """A saved config that today's code cannot run as it was made."""


def _flatten(tree: Mapping, prefix: str = "") -> dict[str, Any]:
    out = {}
    for key, value in tree.items():
        path = f"{prefix}{key}"
        if isinstance(value, Mapping) and value:
            out.update(_flatten(value, path + "."))
        else:
            out[path] = value
    return out


def _neutral(value, neutral) -> bool:
    if neutral is UNUSED:
        return True
    if isinstance(neutral, Mapping):
        return isinstance(value, Mapping) and all(value.get(k) == v for k, v in neutral.items())
    return value == neutral


def _drop_removed(saved: dict, removed: Mapping[str, Any], what: str, source: str) -> dict:
    """`saved` without the removed keys; an error naming those set away from their neutral value."""
    saved, refused = dict(saved), []
    for path, neutral in removed.items():
        *groups, head = path.split(".")
        parent = saved
        for group in groups:   # a field of a group that stays (copied on the way down: `saved` is the caller's)
            if not isinstance(parent.get(group), Mapping):
                parent = None
                break
            parent[group] = dict(parent[group])
            parent = parent[group]
        if parent is not None and head in parent:
            if not _neutral(parent[head], neutral):
                refused.append(f"{what}.{path}={parent[head]!r} (neutral: {neutral!r})")
            del parent[head]
    if refused:
        raise MigrationError(f"{source}: {', '.join(refused)}: removed with its finished experiment "
                             "(training/LESSONS.md names the commit); this run cannot go on with today's code "
                             "(check out that commit's parent to continue it)")
    return saved


def migrate(saved: Mapping, default: config_dict.ConfigDict, what: str, source: str = "saved config",
            renamed: Mapping[str, Any] | None = None, removed: Mapping[str, Any] | None = None
            ) -> config_dict.ConfigDict:
    """`saved` (a run's config as JSON) on today's `default`: renamed keys moved, removed keys dropped or refused
    (RENAMED / REMOVED and the extra `renamed` / `removed`), every key it lacks from `default`, every unknown one
    refused."""
    saved = _drop_removed(saved, {**REMOVED[what], **(removed or {})}, what, source)
    flat = _flatten(saved)
    for old, new in {**RENAMED[what], **(renamed or {})}.items():
        if old in flat:
            new, convert = new if isinstance(new, tuple) else (new, None)
            value = flat.pop(old)
            flat[new] = convert(value) if convert else value
    known = _flatten(default.to_dict())
    unknown = sorted(k for k in flat if k not in known and not any(k.startswith(p + ".") for p in known))
    if unknown:
        raise MigrationError(f"{source}: {what} keys {', '.join(unknown)} are not in today's schema (neither "
                             "renamed nor removed: training/ppo/migration.py)")
    merged = default.to_dict()
    for path, value in flat.items():   # plain dicts: a saved int where today's default is a float stays as run
        *parents, leaf = path.split(".")
        node = merged
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = tuple(value) if isinstance(node.get(leaf), tuple) and isinstance(value, list) else value
    return config_dict.ConfigDict(merged)


def _getup_stage(state: Mapping, source: str) -> str | None:
    """The keyframe stage of a getup run saved before the split (None: a run of today's tasks)."""
    if state["task"] != "getup":
        return None
    stage = state["env_config"].get("stage", "full")
    if stage not in GETUP_STAGES:
        raise MigrationError(f"{source}: env.stage={stage!r} is none of the getup stages {', '.join(GETUP_STAGES)}")
    return stage


def run_task(state: Mapping, source: str = "run state") -> str:
    """Today's task of a saved PPO run (its run_state.json)."""
    stage = _getup_stage(state, source)
    return state["task"] if stage is None else GETUP_STAGES[stage]


def run_configs(state: Mapping, source: str = "run state") -> tuple[config_dict.ConfigDict, config_dict.ConfigDict]:
    """(ppo config, env config) of a saved PPO run (its run_state.json) in today's schema, for run_task's task."""
    task, split = run_task(state, source), SPLIT.get(_getup_stage(state, source), {})
    return (migrate(state["ppo_config"], ppo_config(task, state["preset"]), "ppo", source),
            migrate(state["env_config"], envs.default_config(task), "env", source, **split))
