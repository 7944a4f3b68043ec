"""A saved run's configs come back in today's schema in one place (training/migration.py): every committed
campaign's run state migrates and keeps what it trained with, a key it predates gets today's default, a renamed
key is moved, and a removed or unknown key is refused by its name (unless a removed one is at its neutral value)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from training import envs, migration
from training.configs import ppo_config

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN_STATES = sorted((ROOT / "training" / "campaigns").glob("*/*/run_state.json"))


def _leaves(tree, prefix=""):
    return migration._flatten(tree, prefix)


@pytest.mark.parametrize("path", CAMPAIGN_STATES, ids=lambda p: f"{p.parent.parent.name}/{p.parent.name}")
def test_every_campaign_run_state_migrates_and_keeps_its_settings(path):
    state = json.loads(path.read_text())
    ppo_cfg, env_cfg = migration.run_configs(state, str(path))
    for what, saved, cfg, default in (
            ("ppo", state["ppo_config"], ppo_cfg, ppo_config(state["task"], state["preset"])),
            ("env", state["env_config"], env_cfg, envs.default_config(state["task"]))):
        assert set(_leaves(cfg.to_dict())) == set(_leaves(default.to_dict())), "today's keys, no more, no less"
        today = _leaves(cfg.to_dict())
        for old, new in migration.RENAMED[what].items():    # a renamed key keeps its saved value
            if old in _leaves(saved):
                assert today[new] == _leaves(saved)[old], (old, new)
        removed = set(migration.REMOVED["env"]) | set(migration.REMOVED["ppo"])
        for key, value in _leaves(saved).items():
            if key in today and not any(key == r or key.startswith(r + ".") for r in removed):
                assert list(today[key]) == list(value) if isinstance(value, list) else today[key] == value, key


def test_campaigns_are_there_to_migrate():
    assert len(CAMPAIGN_STATES) >= 1     # getup stage 2 (v12); the student's DAgger stage keeps distill_state.json


def test_a_key_the_run_predates_gets_today_s_default():
    saved = envs.default_config("getup").to_dict()
    del saved["stage1_gate_reward"], saved["reverse_curriculum"]["min_progress"]
    saved["stage"] = "stage1"
    cfg = migration.migrate(saved, envs.default_config("getup"), "env")
    assert cfg.stage1_gate_reward == 0.0 and cfg.reverse_curriculum.min_progress == 0.0 and cfg.stage == "stage1"


def test_a_renamed_key_moves(monkeypatch):
    monkeypatch.setitem(migration.RENAMED, "ppo", {"entropy": "entropy_cost"})
    saved = ppo_config("getup", "toy").to_dict()
    del saved["entropy_cost"]
    saved["entropy"] = 0.125
    assert migration.migrate(saved, ppo_config("getup", "toy"), "ppo").entropy_cost == 0.125


def test_a_removed_key_is_refused_by_name_unless_neutral(monkeypatch):
    monkeypatch.setitem(migration.REMOVED, "env", {"old_knob": 1.0, "old_group": {"prob": 0.0}})
    default = envs.default_config("getup")
    neutral = {**default.to_dict(), "old_knob": 1.0, "old_group": {"prob": 0.0, "policy": "x"}}
    assert "old_knob" not in migration.migrate(neutral, default, "env")
    with pytest.raises(migration.MigrationError, match=r"env\.old_knob=0\.5"):
        migration.migrate({**neutral, "old_knob": 0.5}, default, "env", "runs/x/run_state.json")
    with pytest.raises(migration.MigrationError, match=r"env\.old_group="):
        migration.migrate({**neutral, "old_group": {"prob": 0.5}}, default, "env")


def test_an_unknown_key_is_refused_by_name():
    saved = {**envs.default_config("joystick").to_dict(), "mystery_knob": 3}
    with pytest.raises(migration.MigrationError, match="mystery_knob"):
        migration.migrate(saved, envs.default_config("joystick"), "env")


def test_a_campaign_checkpoint_resumes_on_today_s_code(tmp_path):
    """The kneel campaign's stage-2 checkpoint (the cheapest env to build) goes on: its migrated configs build the
    env and the network, and the call (at its target already: no PPO update) exports its params."""
    import shutil
    from common.artifact import read_artifact
    from training import train
    run = tmp_path / "stand"
    shutil.copytree(ROOT / "training" / "campaigns" / "getup_keyframe" / "stand", run)
    steps = json.loads((run / "run_state.json").read_text())["env_steps"]
    result = train.train("getup", run, steps=steps, resume=True, progress=False, backend="mjx")
    assert result.complete and result.env_steps == steps
    assert read_artifact(result.artifact)[3]["provenance"]["steps"] == steps
    state = json.loads((run / "run_state.json").read_text())
    assert set(state["env_config"]) == set(envs.default_config("getup").to_dict())   # saved back in today's schema


@pytest.mark.parametrize("key, value", [("gravity_scale", 0.5), ("upright_policy", "policies/joystick/joystick.safetensors"),
                                        ("rise_pace", {"weight": 5.0, "waist_from_m": 0.4}),
                                        ("wall_starts", {"prob": 0.3, "joystick_policy": "j", "bank_starts": 8,
                                                         "seed": 1}),
                                        ("push_starts", {"prob": 0.3, "joystick_policy": "j", "bank_starts": 8,
                                                         "seed": 1})])
def test_a_run_that_used_a_finished_experiment_s_knob_is_refused_by_name(key, value):
    saved = {**envs.default_config("getup").to_dict(), key: value}
    with pytest.raises(migration.MigrationError, match=rf"env\.{key}=.*removed with its finished experiment"):
        migration.migrate(saved, envs.default_config("getup"), "env", "runs/old/run_state.json")


def test_the_joystick_hand_over_s_push_share_is_refused_unless_zero():
    saved = envs.default_config("joystick").to_dict()
    saved["handover"] = {**saved["handover"], "push_prob": 0.0}
    assert "push_prob" not in migration.migrate(saved, envs.default_config("joystick"), "env").handover
    saved["handover"]["push_prob"] = 0.2
    with pytest.raises(migration.MigrationError, match=r"env\.handover\.push_prob=0\.2"):
        migration.migrate(saved, envs.default_config("joystick"), "env")
