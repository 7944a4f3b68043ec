"""RL from the imitation policy (training/imitation/finetune.py): the DAgger artifact becomes the PPO policy it is,
the BC term is the DAgger fit's regression on the PPO policy, the planner data are read from the campaign, bad
settings are refused by name; the recipe runner keeps an imitation stage's campaign whole."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from training.core import networks
from training.imitation import config as imitation_config
from training.imitation import dagger, dataset, finetune
from training.imitation.learner import load_learner, new_learner, targets_to_labels
from training.ppo import configs
from training.recipes import base as R
from training.recipes import runner as recipe_runner

CAMPAIGN = dagger.REPO_ROOT / "training" / "campaigns" / "getup_keyframe" / "dagger"
ARTIFACT = CAMPAIGN / imitation_config.ARTIFACT
SIZES = {"state": (52,), "privileged_state": (91,)}


class _Env:
    """What the extension reads of a getup task: its observation sizes and action map."""
    observation_size = SIZES

    def __init__(self, fields):
        self._fields = fields

    def manifest_fields(self):
        return self._fields


@pytest.fixture(scope="module")
def learner():
    from common.artifact import read_artifact
    fields = read_artifact(ARTIFACT)[3]
    fields = {"default_pose": fields["default_pose"], "action_scale": fields["action_scale"]}
    obs, _ = dataset.demonstration_pairs(dagger.DEFAULT_DEMOS)
    like = new_learner(obs[:64], list(imitation_config.default_config().fit.hidden_layer_sizes), 0, fields,
                       -np.ones(23) * 3, np.ones(23) * 3)
    return load_learner(ARTIFACT, like), fields


def _ppo_cfg(**imitation):
    cfg = configs.ppo_config("getup_kneel", "cpu")
    cfg.imitation.update(imitation)
    return cfg


def _network(cfg):
    from brax.training.acme import running_statistics

    from training.core import networks as ppo_networks
    return ppo_networks.network_factory(cfg)(SIZES, 23, preprocess_observations_fn=running_statistics.normalize)


def test_the_artifact_becomes_the_ppo_policy_it_is_with_one_sampling_std(learner):
    fitted, fields = learner
    cfg = _ppo_cfg()
    params = finetune.ImitationFinetune(cfg).initial_params(finetune.read_learner(ARTIFACT), _Env(fields))
    assert params[2] is None                                  # the critic starts fresh
    net = _network(cfg)
    obs, _ = dataset.demonstration_pairs(dagger.DEFAULT_DEMOS)
    x = {"state": obs[:256], "privileged_state": np.zeros((256, 91), np.float32)}
    logits = np.asarray(net.policy_network.apply(params[0], params[1], x))
    np.testing.assert_allclose(np.tanh(logits[:, :23]), fitted.actions(obs[:256]), atol=2e-5)
    std = np.log1p(np.exp(logits[:, 23:])) + networks.MIN_STD
    np.testing.assert_allclose(std, cfg.init_noise_std, rtol=1e-5)


def test_the_bc_term_is_the_dagger_fits_regression_summed_over_joints(learner):
    fitted, fields = learner
    cfg = _ppo_cfg(bc_weight=1.0, demos=str(dagger.DEFAULT_DEMOS))
    ext = finetune.ImitationFinetune(cfg)
    params = ext.initial_params(finetune.read_learner(ARTIFACT), _Env(fields))
    obs, labels = finetune.planner_pairs(cfg, str(ARTIFACT), {k: np.asarray(v) for k, v in fields.items()})
    rounds = json.loads((CAMPAIGN / "data" / "collected.json").read_text())["rounds"]
    assert len(obs) == len(labels) == len(dataset.demonstration_pairs(dagger.DEFAULT_DEMOS)[0]) + \
        sum(r["labels"] for r in rounds.values())             # the demonstrations and every stored round
    last = max(rounds, key=int)
    one = _ppo_cfg(bc_weight=1.0, demos=str(dagger.DEFAULT_DEMOS), first_round=int(last))
    assert len(finetune.planner_pairs(one, str(ARTIFACT), {k: np.asarray(v) for k, v in fields.items()})[0]) == \
        rounds[last]["labels"]                                # one round's expert only
    assert float(finetune.sample_count(params[0])) == finetune.NORMALIZER_COUNT   # held
    pick = np.random.default_rng(0).choice(len(obs), 512, replace=False)
    got = float(finetune.bc_loss(_network(cfg), params[1], params[0], obs[pick], labels[pick],
                                 {k: v[0] for k, v in SIZES.items()}))
    want = np.sum(np.square(fitted.actions(obs[pick]) - labels[pick]), axis=-1).mean()
    assert got == pytest.approx(want, rel=1e-4)


def test_a_fine_tune_going_on_from_another_reads_that_runs_campaign(tmp_path, learner):
    _, fields = learner
    first, second = tmp_path / "rise", tmp_path / "rise_fine"
    for run, init in ((first, str(ARTIFACT)), (second, str(first))):
        (run / "checkpoints").mkdir(parents=True)
        (run / "run_state.json").write_text(json.dumps({"init": init, "ppo_config": {"imitation": {"campaign": ""}}}))
    cfg = _ppo_cfg(bc_weight=1.0, demos=str(dagger.DEFAULT_DEMOS))
    want = finetune.planner_pairs(cfg, str(ARTIFACT), fields)[0]
    for init in (str(second), str(second / "checkpoints" / "000000000080")):   # a run, or one of its checkpoints
        assert len(finetune.planner_pairs(cfg, init, fields)[0]) == len(want)


def test_labels_are_the_fits_own(learner):
    fitted, fields = learner
    q = np.random.default_rng(1).uniform(-2, 2, (16, 23))
    np.testing.assert_array_equal(targets_to_labels(q, fitted.default_pose, fitted.action_scale),
                                  fitted.label_actions(q))
    assert np.all(np.abs(targets_to_labels(q, np.zeros(23), np.full(23, 0.1))) < 1)


def test_bad_settings_are_refused_by_name(tmp_path, learner):
    _, fields = learner
    env = _Env(fields)
    with pytest.raises(ValueError, match="demos"):
        finetune.planner_pairs(_ppo_cfg(bc_weight=1.0), str(ARTIFACT), fields)
    with pytest.raises(ValueError, match="not a DAgger campaign"):
        finetune.planner_pairs(_ppo_cfg(bc_weight=1.0, demos="x", campaign=str(tmp_path)), None, fields)
    with pytest.raises(ValueError, match="does not start from a DAgger artifact or a fine-tune of one"):
        finetune.planner_pairs(_ppo_cfg(bc_weight=1.0, demos="x"), str(tmp_path), fields)
    cfg = _ppo_cfg()
    cfg.init_noise_std = 0.0
    with pytest.raises(ValueError, match="init_noise_std"):
        finetune.ImitationFinetune(cfg).initial_params(finetune.read_learner(ARTIFACT), env)
    with pytest.raises(ValueError, match="observation has 52 entries, the task's 40"):
        finetune.normalizer_state(np.zeros(52, np.float32), np.ones(52, np.float32), 1,
                                  {"state": (40,), "privileged_state": (80,)})


def _imitation_recipe() -> R.Recipe:
    return R.Recipe(name="getup_keyframe", policy="p", summary="",
                    stages=(R.Stage("dagger", kind="imitation", steps=3),
                            R.Stage("rise", task="getup_kneel", steps=10, init="dagger")))


def test_an_imitation_stage_is_complete_at_its_rounds_and_kept_whole_in_the_campaign(tmp_path, monkeypatch):
    recipe = _imitation_recipe()
    dagger_stage, rise = recipe.stages
    run = tmp_path / "runs" / "getup_keyframe" / "dagger"
    (run / "data").mkdir(parents=True)
    (run / "data" / "round_01.npz").write_bytes(b"labels")
    state = {"config": {"dagger": {"rounds": 8}}, "rounds": [{"round": 0}, {"round": 1}]}
    (run / imitation_config.STATE).write_text(json.dumps(state))
    root = tmp_path / "runs"
    assert not recipe_runner.stage_complete(root, recipe, dagger_stage)
    state["rounds"].append({"round": 2})
    (run / imitation_config.STATE).write_text(json.dumps(state))
    assert recipe_runner.stage_complete(root, recipe, dagger_stage)
    assert recipe_runner.stage_artifact(run, recipe, dagger_stage) == run / imitation_config.ARTIFACT
    assert recipe_runner._init_path("dagger", recipe, root) == run / imitation_config.ARTIFACT
    # a complete PPO stage from it supersedes it, but its labels stay in the campaign
    (root / "getup_keyframe" / "rise").mkdir()
    (root / "getup_keyframe" / "rise" / "run_state.json").write_text(json.dumps({"env_steps": 10, "target_steps": 10}))
    monkeypatch.setattr(R, "load", lambda name: recipe)
    monkeypatch.setattr(R, "names", lambda: ["getup_keyframe"])
    assert recipe_runner.superseded(root, recipe, dagger_stage)
    saved = recipe_runner.save_campaign("getup_keyframe", root, tmp_path / "campaigns")
    kept = tmp_path / "campaigns" / "getup_keyframe" / "dagger"
    assert kept in saved and (kept / "data" / "round_01.npz").read_bytes() == b"labels"
    shutil.rmtree(run)
    recipe_runner.restore_campaign(recipe, dagger_stage, root, tmp_path / "campaigns")
    assert json.loads((run / imitation_config.STATE).read_text()) == state
    # rounds run into the campaign folder itself are not overwritten by the run's older copy
    more = {**state, "rounds": [*state["rounds"], {"round": 3}]}
    (kept / imitation_config.STATE).write_text(json.dumps(more))
    (kept / "data" / "round_03.npz").write_bytes(b"newer labels")
    assert kept in recipe_runner.save_campaign("getup_keyframe", root, tmp_path / "campaigns")
    assert (kept / "data" / "round_03.npz").read_bytes() == b"newer labels"
    assert json.loads((kept / imitation_config.STATE).read_text()) == more


def test_a_new_run_names_the_campaign_its_start_reads():
    """A fine-tune of a PPO run that read its DAgger campaign through its own start names that campaign in its
    config, so its kept run state resumes on a clone without the start; a named campaign is left alone."""
    cfg = configs.ppo_config("getup_kneel", "cpu")
    cfg.imitation.update(demos="training/campaigns/getup_keyframe/demos", bc_weight=3.0, campaign="")
    finetune.pin_campaign(cfg, "training/campaigns/getup_keyframe/rise_rolled/checkpoints/000006164480")
    assert cfg.imitation.campaign == "training/campaigns/getup_keyframe/dagger"
    cfg.imitation.campaign = "elsewhere"
    finetune.pin_campaign(cfg, "training/campaigns/getup_keyframe/rise_rolled/checkpoints/000006164480")
    assert cfg.imitation.campaign == "elsewhere"
