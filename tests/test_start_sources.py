"""The start sources as a registry (training/envs/starts/): every source's module owns its config group and, for
a share of a getup task's fallen starts, its bank function; the task configs hold exactly the registered groups,
the getup tasks check the shares before rolling anything, the recipe runner shrinks every registered bank at toy
size, and the evaluation's mid-fall starts are found by name."""
from __future__ import annotations

import pytest

from training import envs
from training.envs import starts
from training.evaluation import batch as evaluate
from training.recipes import runner as recipe_runner

SHARES = tuple(s for s in starts.SOURCES if "prob" in s.functions()[0]())


@pytest.mark.parametrize("source", starts.SOURCES, ids=lambda s: s.group)
def test_every_source_owns_its_config_group(source):
    config, bank = source.functions()
    group = config()
    assert group.get("prob", 0.0) == 0.0                                          # optional sources off by default
    assert not source.source_key or group[source.source_key] == ""
    assert bank is None or set(source.tasks) <= set(starts.GETUP_TASKS)           # banks replace fallen starts
    for task in source.tasks:
        assert envs.default_config(task)[source.group].to_dict() == group.to_dict()
    others = set(envs.TASKS) - set(source.tasks)
    assert not any(source.group in envs.default_config(task) for task in others)


def test_the_getup_task_checks_the_shares_before_rolling_a_bank():
    with pytest.raises(ValueError, match=r"knockdown_starts.prob > 0 needs knockdown_starts.joystick_policy"):
        envs.make("getup", config_overrides={"fallen.bank_starts": 2, "knockdown_starts.prob": 0.5})
    with pytest.raises(ValueError, match=r"knockdown_starts.prob must be in \[0, 1\]"):
        envs.make("getup", config_overrides={"fallen.bank_starts": 2, "knockdown_starts.prob": 1.5})


def test_toy_stages_shrink_every_banked_source():
    for source in SHARES:
        if "bank_starts" in source.functions()[0]():
            toy = recipe_runner._overrides({f"env.{source.group}.prob": 0.5}, toy=True)
            assert f"env.{source.group}.bank_starts={recipe_runner.TOY_BANK_STARTS}" in toy


def test_mid_fall_starts_by_name():
    assert set(evaluate.START_KINDS) == {"fallen", *starts.LANDINGS}
    assert set(evaluate.JOYSTICK_STARTS) == set(starts.LANDINGS)
    for kind in starts.LANDINGS:
        assert callable(starts.landing_bank(kind))
    with pytest.raises(ValueError, match="mid-fall start 'ladder': one of knockdown, push, wall"):
        starts.landing_bank("ladder")
