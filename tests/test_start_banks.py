"""The start sources as a registry (training/envs/start_banks.py): every source's module owns its config group
and bank function, the task configs hold exactly the registered groups, the getup env checks the shares before
rolling anything, and the recipe runner shrinks every registered bank at toy size."""
from __future__ import annotations

import pytest

from training import envs, recipe_runner
from training.envs import start_banks


@pytest.mark.parametrize("source", start_banks.SOURCES, ids=lambda s: f"{s.task}.{s.group}")
def test_every_source_owns_its_config_group_and_bank(source):
    config, bank = source.functions()
    group = config()
    assert group.prob == 0.0 and {"bank_starts", "seed"} <= set(group)          # off by default, seeded
    assert not source.source_key or group[source.source_key] == ""
    assert (bank is None) == (source.task != "getup")                            # getup's replace fallen starts
    assert envs.default_config(source.task)[source.group].to_dict() == group.to_dict()


def test_the_getup_env_checks_the_shares_before_rolling_a_bank():
    with pytest.raises(ValueError, match=r"knockdown_starts.prob > 0 needs knockdown_starts.joystick_policy"):
        envs.make("getup", config_overrides={"fallen_bank_size": 2, "knockdown_starts.prob": 0.5})
    with pytest.raises(ValueError, match=r"knockdown_starts.prob must be in \[0, 1\]"):
        envs.make("getup", config_overrides={"fallen_bank_size": 2, "knockdown_starts.prob": 1.5})


def test_toy_stages_shrink_every_registered_bank():
    for source in start_banks.SOURCES:
        toy = recipe_runner._overrides({f"env.{source.group}.prob": 0.5}, toy=True)
        assert f"env.{source.group}.bank_starts={recipe_runner.TOY_BANK_STARTS}" in toy
