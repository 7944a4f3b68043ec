"""A saved run's task and configs come back in today's schema in one place (training/ppo/migration.py): every committed
campaign's run state migrates, keeps what it trained with and resumes, a getup run from before the getup tasks
were split becomes its stage's task, a key it predates gets today's default, a renamed key is moved, and a removed
or unknown key is refused by its name (unless a removed one is at its neutral value)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from training import envs
from training.ppo import migration
from training.ppo.configs import ppo_config

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN_STATES = sorted((ROOT / "training" / "campaigns").glob("*/*/run_state.json"))


def _leaves(tree, prefix=""):
    return migration._flatten(tree, prefix)


def _moved(state) -> dict:
    """old dotted path → (today's path, conversion) of a saved env config (RENAMED, and SPLIT for an old getup run)."""
    stage = state["env_config"].get("stage", "full") if state["task"] == "getup" else None
    renamed = {**migration.RENAMED["env"], **migration.SPLIT.get(stage, {}).get("renamed", {})}
    return {old: new if isinstance(new, tuple) else (new, lambda v: v) for old, new in renamed.items()}


def _removed(state) -> set:
    stage = state["env_config"].get("stage", "full") if state["task"] == "getup" else None
    return set(migration.REMOVED["env"]) | set(migration.SPLIT.get(stage, {}).get("removed", {}))


@pytest.mark.parametrize("path", CAMPAIGN_STATES, ids=lambda p: f"{p.parent.parent.name}/{p.parent.name}")
def test_every_campaign_run_state_migrates_and_keeps_its_settings(path):
    state = json.loads(path.read_text())
    task = migration.run_task(state, str(path))
    ppo_cfg, env_cfg = migration.run_configs(state, str(path))
    for cfg, default in ((ppo_cfg, ppo_config(task, state["preset"])), (env_cfg, envs.default_config(task))):
        assert set(_leaves(cfg.to_dict())) == set(_leaves(default.to_dict())), "today's keys, no more, no less"
    today, saved = _leaves(env_cfg.to_dict()), _leaves(state["env_config"])
    moved, removed = _moved(state), _removed(state)
    for old, (new, convert) in moved.items():             # a renamed key keeps its saved value (converted)
        if old in saved:
            assert today[new] == convert(saved[old]), (old, new)
    for key, value in saved.items():
        if key in today and key not in moved and not any(key == r or key.startswith(r + ".") for r in removed):
            assert list(today[key]) == list(value) if isinstance(value, list) else today[key] == value, key
    for key, value in _leaves(state["ppo_config"]).items():
        assert _leaves(ppo_cfg.to_dict())[key] == (tuple(value) if isinstance(value, list) else value), key


def test_campaigns_are_there_to_migrate():
    assert len(CAMPAIGN_STATES) >= 1     # the kneel's stage 2 (stand), a getup run from before the tasks' split


def test_a_getup_run_before_the_split_comes_back_as_its_stage_s_task():
    """task "getup" with env_config "stage": stage 1 → getup_kneel with its stage-1 keys moved (its start mix,
    gate and slope rewards; the sag end is gone: only its neutral 0 loads), stage 2 → getup_stand, full → getup;
    the keys a stage never read are dropped, the energy weight becomes the energy term's negative scale."""
    old = {"stage": "stage1", "start_probs": [0.4, 0.4, 0.2], "stage1_start_probs": [0.7, 0.3, 0.0],
           "stage2_start_probs": [0.0, 1.0, 0.0], "stage1_gate_reward": 1.0, "stage1_upright_reward": 0.5,
           "stage1_drop_below_m": 0.0, "stage2_fall_trunk_height_m": 0.35, "stage2_fall_up_z": 0.7,
           "gate_latches": True, "energy_weight": 0.01, "reverse_curriculum": {"max_progress": 2.0}}
    state = {"task": "getup", "preset": "cpu", "ppo_config": {}, "env_config": old}
    assert migration.run_task(state) == "getup_kneel"
    env = migration.run_configs(state)[1]
    assert list(env.start_probs) == [0.7, 0.3, 0.0] and "drop_below_gate_m" not in env
    assert env.reward.scales.to_dict() == {"height": 1.0, "pose": 1.0, "gate": 1.0, "upright": 0.5, "energy": -0.01}
    with pytest.raises(migration.MigrationError, match=r"env\.stage1_drop_below_m=0\.03"):
        migration.run_configs({**state, "env_config": {**old, "stage1_drop_below_m": 0.03}}, "runs/x/run_state.json")
    stand = {**state, "env_config": {"stage": "stage2", "stage2_fall_up_z": 0.6, "stage1_gate_reward": 1.0}}
    assert migration.run_task(stand) == "getup_stand" and migration.run_configs(stand)[1].fall_up_z == 0.6
    full = {**state, "env_config": {"gate_latches": False, "stage2_fall_up_z": 0.6, "energy_weight": 0.0}}
    assert migration.run_task(full) == "getup"          # a run before "stage" existed: the full task
    assert set(migration.run_configs(full)[1]) == set(envs.default_config("getup"))
    with pytest.raises(migration.MigrationError, match=r"env\.stage='stage3'"):
        migration.run_task({**state, "env_config": {"stage": "stage3"}}, "runs/x/run_state.json")


@pytest.mark.parametrize("stage, latches", [("full", True), ("stage2", True), ("stage1", False)])
def test_a_run_with_another_gate_than_its_task_s_is_refused(stage, latches):
    """gate_latches is gone: the kneel task's gate latches, the others' is §4.8's per-step condition; a run made
    the other way cannot go on as it was made (LESSONS.md, "Knobs and modules removed")."""
    state = {"task": "getup", "preset": "cpu", "ppo_config": {},
             "env_config": {"stage": stage, "gate_latches": latches}}
    with pytest.raises(migration.MigrationError, match=rf"env\.gate_latches={latches}"):
        migration.run_configs(state, "runs/old/run_state.json")


def test_a_kneel_run_with_the_sag_end_and_tracking_knobs_loads_while_they_are_off():
    """drop_below_gate_m, reward.scales.track and the tracking group are gone (no recipe or card sets them): a
    kneel run saved with them at their neutral values (off) loads as today's task; one that used them is refused
    by the key's name."""
    saved = envs.default_config("getup_kneel").to_dict()
    saved["drop_below_gate_m"] = 0.0
    saved["reward"]["scales"]["track"] = 0.0
    saved["tracking"] = {"height_sigma_m": 0.1, "end_height_m": 0.0}
    cfg = migration.migrate(saved, envs.default_config("getup_kneel"), "env")
    assert cfg.to_dict() == envs.default_config("getup_kneel").to_dict()
    for key, value, match in (("drop_below_gate_m", 0.03, r"env\.drop_below_gate_m=0\.03"),
                              ("track", 1.0, r"env\.reward\.scales\.track=1\.0")):
        bad = json.loads(json.dumps(saved))
        (bad["reward"]["scales"] if key == "track" else bad)[key] = value
        with pytest.raises(migration.MigrationError, match=match):
            migration.migrate(bad, envs.default_config("getup_kneel"), "env", "runs/x/run_state.json")


def test_a_full_task_run_with_the_upright_term_loads_only_while_it_is_off():
    """The full task's reward.scales.upright is gone (the kneel task keeps its own): a getup run saved with it at 0
    loads as today's task, one that set it is refused by the key's name."""
    saved = envs.default_config("getup").to_dict()
    saved["reward"]["scales"]["upright"] = 0.0
    state = {"task": "getup", "preset": "cpu", "ppo_config": {}, "env_config": saved}
    assert migration.run_configs(state)[1].to_dict() == envs.default_config("getup").to_dict()
    saved["reward"]["scales"]["upright"] = 1.0
    with pytest.raises(migration.MigrationError, match=r"env\.reward\.scales\.upright=1\.0"):
        migration.run_configs(state, "runs/x/run_state.json")


def test_a_unified_run_s_getup_energy_weight_becomes_its_energy_scale():
    """The unified env's skills reward weighs the getup expert's terms by reward.getup.scales as the getup tasks'
    reward.scales do: a saved positive reward.getup.energy_weight W becomes scales.energy −W."""
    saved = envs.default_config("unified").to_dict()
    del saved["reward"]["getup"]["scales"]
    saved["reward"]["getup"]["energy_weight"] = 0.01
    cfg = migration.migrate(saved, envs.default_config("unified"), "env")
    assert cfg.reward.getup.scales.to_dict() == {"height": 1.0, "pose": 1.0, "energy": -0.01}
    assert cfg.to_dict() == envs.default_config("unified").to_dict()


def test_a_key_the_run_predates_gets_today_s_default():
    saved = envs.default_config("getup_kneel").to_dict()
    del saved["reward"]["scales"]["upright"], saved["demo_starts"]["gated_only"], saved["action_space"]
    cfg = migration.migrate(saved, envs.default_config("getup_kneel"), "env")
    assert cfg.reward.scales.upright == 0.0 and cfg.demo_starts.gated_only is False and cfg.action_space == "full"


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


CAMPAIGN_RUNS = sorted(p.parent for p in CAMPAIGN_STATES)


@pytest.mark.slow
@pytest.mark.parametrize("stored", CAMPAIGN_RUNS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_stored_campaign_resumes_on_today_s_code(tmp_path, stored):
    """Each stored campaign's checkpoint goes on: its migrated configs build its task's env and the network, and
    the call (at its steps already: no PPO update) exports its params and saves the run back in today's schema."""
    import shutil

    from common.artifact import read_artifact
    from training.ppo import train
    from training.recipes.runner import TOY_BANK_STARTS
    run = tmp_path / stored.name
    shutil.copytree(stored, run)
    state = json.loads((run / "run_state.json").read_text())
    for group in state["env_config"].values():   # start banks at toy size: building them rolls policies out
        if isinstance(group, dict) and "bank_starts" in group:
            group["bank_starts"] = TOY_BANK_STARTS
    (run / "run_state.json").write_text(json.dumps(state))
    task, steps = migration.run_task(state), state["env_steps"]
    result = train.train(task, run, steps=steps, resume=True, progress=False, backend="mjx")
    assert result.complete and result.env_steps == steps
    assert read_artifact(result.artifact)[3]["provenance"]["steps"] == steps
    state = json.loads((run / "run_state.json").read_text())
    assert state["task"] == task and set(state["env_config"]) == set(envs.default_config(task).to_dict())


@pytest.mark.parametrize("key, value", [("gravity_scale", 0.5),
                                        ("upright_policy", "policies/joystick/joystick.safetensors"),
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
