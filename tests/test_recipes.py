"""Every recipe (training/recipes/) runs end to end at toy size on every CI run, so none rots: its stages chain
(init from the stage before, @RECIPE/STAGE references into the same runs root), its config diffs apply to
today's task configs, and its provenance names the recipe and its hash. Also the recipe CLI's errors and
the campaign round trip (save → a fresh runs root → --resume restores and goes on)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from common import events, keyframe_chain
from common.artifact import read_artifact, stitched_teacher
from training import cli
from training.core import checkpoints
from training.recipes import base as R
from training.recipes import campaign
from training.recipes import runner as recipe_runner

ROOT = Path(__file__).resolve().parents[1]
TOY_ENV = {**os.environ,       # XLA_FLAGS: tests/conftest.py's
           "PYTHONPATH": f"{ROOT}:{ROOT / 'build' / 'gen' / 'python'}"}
WORKERS = 2   # the CI machine's cores; XLA compilation is mostly single-threaded


def _waves(names: list[str]) -> list[list[str]]:
    """The recipes in waves: each wave reads stage artifacts only of recipes of earlier waves."""
    waves, done = [], set()
    pending = R.in_dependency_order(names)
    while pending:
        wave = [n for n in pending if R.load(n).depends_on() <= done]
        waves.append(wave)
        done |= set(wave)
        pending = [n for n in pending if n not in wave]
    return waves


@pytest.fixture(scope="module")
def toy_root(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("recipes")
    for wave in _waves(R.names()):
        # split a wave over the workers, each running its recipes one after the other (one JAX process each)
        groups = [wave[i::WORKERS] for i in range(WORKERS) if wave[i::WORKERS]]
        procs = [subprocess.Popen(
            [sys.executable, "-c", "import sys; from training import cli\n"
             "for n in sys.argv[2:]:\n"
             "    assert cli.main(['recipe', n, '--toy', '--no-progress', '--out', sys.argv[1]]) == 0",
             str(root), *group], cwd=ROOT, env=TOY_ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            for group in groups]
        for group, proc in zip(groups, procs):
            text = proc.communicate(timeout=1200)[0]
            assert proc.returncode == 0, f"toy recipes {group}: exit {proc.returncode}\n{text[-4000:]}"
    return root


@pytest.mark.slow
@pytest.mark.parametrize("name", R.names())
def test_every_recipe_runs_to_its_policy_at_toy_size(toy_root, name):
    recipe = R.load(name)
    for stage in recipe.stages:
        assert recipe_runner.stage_complete(toy_root, recipe, stage), f"{name}: stage {stage.name} incomplete"
    final = recipe_runner.stage_dirs(toy_root, recipe, recipe.stages[-1])[-1]
    artifact = recipe_runner.artifact_name(recipe, recipe.stages[-1])   # the policy's; a chain's member's own
    assert artifact == (f"{recipe.policy}_{recipe.stages[-1].name}" if recipe.chain else recipe.policy)
    manifest = read_artifact(final / f"{artifact}.safetensors")[3]
    assert manifest["name"] == artifact and manifest["trained"] is False     # toy: never trained
    if recipe.stages[-1].kind != "random_init":
        assert manifest["provenance"]["recipe"] == {"name": name, "stage": recipe.stages[-1].name,
                                                    "sha256": R.content_hash(name)}


@pytest.mark.slow
def test_the_kneeling_joystick_expert_starts_from_the_shipped_one_on_the_chains_handovers(toy_root):
    """joystick_kneeling: a fine-tune of the shipped artifact (at its own network size, even at toy scale), its
    hand-over starts rolled by the keyframe chain's stand from the kneels its rise reaches."""
    recipe = R.load("joystick_kneeling")
    run = recipe_runner.stage_dirs(toy_root, recipe, recipe.stages[0])[-1]
    state = json.loads((run / checkpoints.RUN_STATE).read_text())
    assert state["init"] == recipe.stages[0].init == "policies/joystick_handover/joystick_handover.safetensors"
    assert state["ppo_config"]["policy_hidden_layer_sizes"] == [512, 256, 128]
    handover = state["env_config"]["handover"]
    assert handover["rise_policy"] and handover["roll_policy"] and handover["up_error"] == events.KNEEL_BAND_UP_ERROR


@pytest.mark.slow
def test_the_student_fine_tune_starts_from_dagger_and_exports_a_student(toy_root):
    """The student's PPO stage starts from the walls stage's DAgger checkpoint and exports, at its end and from
    any kept checkpoint, the artifact the runtime runs: output rule linear, the student's layer shapes, and
    the teacher it was fine-tuned toward."""
    from training.ppo import train
    run = toy_root / "student" / "finetune"
    state = json.loads((run / checkpoints.RUN_STATE).read_text())
    assert Path(state["init"]).parent.parent == toy_root / "student" / "walls"
    assert state["ppo_config"]["teacher"]["bc_weight"] > 0 and state["bc_count_start"] > 0
    final = read_artifact(run / "student.safetensors")
    kept = read_artifact(train.export_checkpoint(run, checkpoints.checkpoint_steps(run), "kept",
                                                  like=run / "student.safetensors"))
    walls = read_artifact(toy_root / "student" / "walls" / "student_walls.safetensors")
    teacher = {k: state["ppo_config"]["teacher"][k] for k in ("getup", "joystick")}
    for artifact in (final, kept):
        assert artifact[3]["output_rule"] == "linear"
        assert stitched_teacher(artifact[3]) == teacher     # the demo and Fig. 5.1 follow it with its teacher
        assert [w.shape for w, _ in artifact[0]] == [w.shape for w, _ in walls[0]]


@pytest.mark.slow
def test_the_kneel_rise_starts_from_the_dagger_learner_with_the_bc_term(toy_root):
    """getup_keyframe's first PPO stage starts from its imitation stage's artifact and ends at its end_at
    checkpoint; `rise` starts from that checkpoint's export (a DAgger round was rolled out by it), reads the BC
    term's data from the campaign and exports its kept checkpoints (mid-run: the manifest fields of the artifact
    it started from)."""
    from training.imitation import config as imitation_config
    from training.imitation import finetune
    from training.ppo import train
    dagger = toy_root / "getup_keyframe" / "dagger"
    explore = toy_root / "getup_keyframe" / "rise_explore"
    first = json.loads((explore / checkpoints.RUN_STATE).read_text())
    assert Path(first["init"]) == dagger / imitation_config.ARTIFACT
    assert (first["env_steps"], first["target_steps"]) == (recipe_runner.TOY_END_AT_STEPS[1],
                                                           recipe_runner.TOY_END_AT_STEPS[0])
    run = toy_root / "getup_keyframe" / "rise"
    state = json.loads((run / checkpoints.RUN_STATE).read_text())
    assert Path(state["init"]) == explore / "getup_keyframe_rise_explore.safetensors"
    assert state["ppo_config"]["imitation"]["bc_weight"] > 0 and state["bc_count_start"] == finetune.NORMALIZER_COUNT
    from training.ppo import kneel_report
    (run / "getup_keyframe_rise.safetensors").rename(run / "moved.safetensors")   # as mid-run: no export yet
    try:
        kept = read_artifact(train.export_checkpoint(run, checkpoints.checkpoint_steps(run), "kept"))
        # its figures per checkpoint (exports with another artifact's fields): one row each, evaluated once
        rows = kneel_report.report(run, seeds=2, seconds=0.1, like=dagger / imitation_config.ARTIFACT)
    finally:
        (run / "moved.safetensors").rename(run / "getup_keyframe_rise.safetensors")
    dagger_layers = read_artifact(dagger / imitation_config.ARTIFACT)[0]
    assert kept[3]["output_rule"] == "tanh_normal"
    assert [w.shape for w, _ in kept[0]] == [w.shape for w, _ in dagger_layers]
    assert [r["env_steps"] for r in rows] == [checkpoints.checkpoint_steps(run)] and rows[0]["bc_weight"] > 0
    assert 0.0 <= rows[0]["kneeled"] <= rows[0]["reached_kneel"] <= 1.0
    assert kneel_report.report(run, seeds=2, seconds=0.1, log=lambda _: pytest.fail("evaluated again")) == rows
    assert "| env steps |" in (run / kneel_report.REPORT).read_text()
    fine = json.loads((toy_root / "getup_keyframe" / "rise_fine" / checkpoints.RUN_STATE).read_text())
    assert Path(fine["init"]).is_relative_to(run)                       # rise's newest checkpoint
    # its data: rise's campaign, named in its own config (it resumes where rise's checkpoint is not kept)
    assert Path(fine["ppo_config"]["imitation"]["campaign"]).resolve() == dagger.resolve()


@pytest.mark.slow
def test_the_dagger_rounds_between_the_rise_stages_are_rolled_out_by_them(toy_root):
    """The stage-1 campaign holds every round of its imitation stages, in the recipe's order, each rolled out by
    its stage's policy from its lying side, with its expert; rise_best's BC term reads the best-of-K rounds."""
    from training.imitation import config as imitation_config
    recipe = R.load("getup_keyframe")
    dagger = toy_root / "getup_keyframe" / "dagger"
    rows = json.loads((dagger / imitation_config.STATE).read_text())["rounds"]
    last = [s for s in recipe.stages if s.kind == "imitation"][-1]
    assert [r["round"] for r in rows] == list(range(recipe.rounds_through(last)))
    for s in (s for s in recipe.stages if s.kind == "imitation" and s.policy):
        policy = recipe_runner.stage_artifact(toy_root / "getup_keyframe" / s.policy, recipe, recipe.stage(s.policy))
        for row in rows[recipe.rounds_through(s) - s.steps:recipe.rounds_through(s)]:
            assert Path(row["policy_from"]) == policy and row.get("lying", "") == s.lying, row
            assert row["expert"]["best_of_k"]["k"] == s.config.get("dagger.expert.best_of_k.k", 0)
    best = json.loads((toy_root / "getup_keyframe" / "rise_best" / checkpoints.RUN_STATE).read_text())
    assert recipe.stage("rise_best").config["ppo.imitation.first_round"] == \
        recipe.rounds_through(recipe.stage("dagger_back"))
    assert recipe.stage("rise_clean").config["ppo.imitation.first_round"] == \
        recipe.rounds_through(recipe.stage("dagger_best"))
    assert best["ppo_config"]["imitation"]["first_round"] == 0          # a toy best-of-K round labels nothing
    assert best["end_at"] == recipe_runner.TOY_END_AT_STEPS[1] and best["env_steps"] == best["end_at"]


@pytest.mark.slow
def test_a_fine_tune_starts_from_the_stage_before(toy_root):
    recipe = R.load("joystick")
    state = json.loads((toy_root / "joystick" / "yaw" / checkpoints.RUN_STATE).read_text())
    assert Path(state["init"]).parent.parent == toy_root / "joystick" / "walk"
    assert state["env_config"]["reward"]["scales"]["tracking_ang_vel"] == \
        recipe.stage("yaw").config["env.reward.scales.tracking_ang_vel"]


@pytest.mark.slow
def test_a_campaign_goes_on_from_training_campaigns_on_a_fresh_machine(toy_root, tmp_path):
    campaigns, fresh = tmp_path / "campaigns", tmp_path / "runs"
    (campaigns / "joystick" / "walk").mkdir(parents=True)    # from an earlier save, before yaw was complete
    saved = recipe_runner.save_campaign("joystick", toy_root, campaigns)
    assert {p.name for p in saved} == {"sharp"}     # walk → yaw → sharp: the newest of the chain only
    assert sorted(p.name for p in (campaigns / "joystick").iterdir()) == ["sharp"]
    kept = sorted(p.name for p in (campaigns / "joystick" / "sharp").iterdir())
    assert kept == ["checkpoints", "learning_curve.png", "metrics.csv", "run_state.json"]
    assert len(list((campaigns / "joystick" / "sharp" / "checkpoints").iterdir())) == 1   # the newest only
    recipe = R.load("joystick")
    stage = recipe.stage("sharp")
    recipe_runner.restore_campaign(recipe, stage, fresh, campaigns)
    assert recipe_runner.stage_complete(fresh, recipe, stage)


def test_recipes_are_listed_with_their_policies(capsys):
    assert cli.main(["recipe", "--list"]) == 0
    out = capsys.readouterr().out
    for name in R.names():
        assert f"{name}: policies/{R.load(name).policy}/" in out


def test_every_shipped_policy_has_a_recipe_and_a_card():
    shipped = sorted(p.name for p in (ROOT / "policies").iterdir() if p.is_dir())
    recipes = {R.load(n).policy: R.load(n) for n in R.names()}
    for name in shipped:
        assert name in recipes, f"policies/{name}/ has no recipe in training/recipes/"
        # an artifact, or a keyframe chain's manifest beside its members
        expected = keyframe_chain.MANIFEST if recipes[name].chain else f"{name}.safetensors"
        assert (ROOT / "policies" / name / expected).exists(), f"policies/{name}/ has no {expected}"
        assert (ROOT / "policies" / name / checkpoints.CARD).exists(), f"policies/{name}/ has no CARD.md"


def test_recipe_errors_name_the_problem(capsys, tmp_path):
    assert cli.main(["recipe", "no_such_recipe", "--out", str(tmp_path)]) == 2
    assert "unknown recipe 'no_such_recipe'" in capsys.readouterr().err
    assert cli.main(["recipe", "joystick", "--stage", "nope", "--out", str(tmp_path)]) == 2
    assert "recipe joystick has no stage 'nope'" in capsys.readouterr().err
    assert cli.main(["recipe", "joystick", "--stage", "yaw", "--out", str(tmp_path)]) == 2
    assert "walk: not run under" in capsys.readouterr().err
    assert cli.main(["recipe"]) == 2
    with pytest.raises(ValueError, match="init 'later' is not an earlier stage"):
        R.Recipe("x", "x", "", (R.Stage("a", init="later"), R.Stage("later")))
    shipped = "policies/joystick/joystick.safetensors"
    R.Recipe("x", "x", "", (R.Stage("a", init=shipped, init_artifact=True),))      # a fine-tune of what ships
    with pytest.raises(ValueError, match="with init_artifact, a shipped artifact under policies/"):
        R.Recipe("x", "x", "", (R.Stage("a", init=shipped),))
    with pytest.raises(ValueError, match="a teacher is getup and joystick"):
        R.Recipe("x", "x", "", (R.Stage("a", kind="distill"),))
    with pytest.raises(ValueError, match=r"roll, rise and stand \(the keyframe chain\)"):
        R.Recipe("x", "x", "", (R.Stage("a", kind="distill", teacher={"roll": "r", "rise": "s"}),))
    R.Recipe("x", "x", "", (R.Stage("a", kind="distill", teacher={"roll": "r", "rise": "s", "stand": "t"}),))
    with pytest.raises(ValueError, match="a teacher is getup and joystick"):
        R.Recipe("x", "x", "", (R.Stage("a", teacher={"getup": "g"}),))
    with pytest.raises(ValueError, match="advance_at is a PPO stage's"):
        R.Recipe("x", "x", "", (R.Stage("a", kind="distill", teacher={"getup": "g", "joystick": "j"},
                                        advance_at=("eval/episode_gate_reached", 0.8)),))


def test_a_backplay_stage_advances_once_its_metric_has_risen(tmp_path):
    """advance_at: the run stops at the first evaluation after trained steps with the metric at the value (its
    checkpoint saved just before), records it, and its recipe stage counts as complete."""
    from types import SimpleNamespace

    from training.ppo import train
    state = {"name": "s", "env_steps": 0, "target_steps": 1000, "minutes": 0.0, "calls": [],
             "advance_at": ["eval/episode_gate_reached", 0.8]}
    run = train._Run(tmp_path, state, None, None, None, None)
    epochs = train._Epochs(run, SimpleNamespace(backend="cpu"), None, "test", None, False, 0.0)
    epochs.progress_fn(0, {"eval/episode_gate_reached": 0.9})        # the untrained policy's evaluation
    epochs.progress_fn(100, {"eval/episode_gate_reached": 0.5})
    with pytest.raises(train._Advanced):
        epochs.progress_fn(200, {"eval/episode_gate_reached": 0.85})
    saved = json.loads((tmp_path / checkpoints.RUN_STATE).read_text())
    assert saved["advanced"] == {"env_steps": 200, "eval/episode_gate_reached": 0.85}
    recipe = R.Recipe("r", "r", "", (R.Stage("near", task="getup", advance_at=("eval/episode_gate_reached", 0.8)),))
    (tmp_path / "r" / "near").mkdir(parents=True)
    (tmp_path / "r" / "near" / checkpoints.RUN_STATE).write_text(json.dumps(saved))
    assert recipe_runner.stage_complete(tmp_path, recipe, recipe.stage("near"))


def test_a_stage_kept_by_a_later_complete_stage_is_not_rerun(tmp_path):
    """A campaign keeps only the newest stage of a chain: the stages it started from are superseded."""
    recipe = R.load("getup_keyframe")
    stand = recipe.stage("stand")
    out = tmp_path / "getup_keyframe" / "stand"
    out.mkdir(parents=True)
    (out / checkpoints.RUN_STATE).write_text(json.dumps({"env_steps": 10, "target_steps": 10}))
    assert recipe_runner.stage_complete(tmp_path, recipe, stand)
    assert recipe_runner.superseded(tmp_path, recipe, recipe.stage("stand_path"))
    assert recipe_runner.superseded(tmp_path, recipe, recipe.stage("stand_swing"))
    assert not recipe_runner.superseded(tmp_path, recipe, recipe.stage("stand_band"))   # later than stand
    # still read by another stage's config or teacher (the hand-over's getup, the student's teacher): kept in
    # its campaign though superseded
    knockdown = R.load("getup_knockdown")
    assert recipe_runner.referenced(knockdown, knockdown.stage("energy"))
    assert not recipe_runner.referenced(knockdown, knockdown.stage("gated"))


def test_toy_size_keeps_the_env_diff_and_shrinks_the_landing_banks():
    stage = R.load("getup_knockdown").stage("landing_bank")
    toy = recipe_runner._overrides(dict(stage.config), toy=True)
    assert not any(o.startswith(("ppo.", "bc.")) for o in toy)          # the toy preset's sizes and rates
    assert "env.knockdown_starts.prob=0.8" in toy and \
        f"env.knockdown_starts.bank_starts={recipe_runner.TOY_BANK_STARTS}" in toy
    finetune = R.load("student").stage("finetune")      # what the learner is stays the stage's at toy size
    toy = recipe_runner._overrides(dict(finetune.config), toy=True)
    assert "ppo.policy_distribution='normal'" in toy and any(o.startswith("ppo.teacher.bc_weight=") for o in toy)
    assert not any(o.startswith(("ppo.learning_rate", "ppo.value_warmup_steps")) for o in toy)
    chain = recipe_runner._overrides({"bc.handover_up_error": 0.05, "bc.learning_rate": 1e-4, "bc.num_evals": 7},
                                     toy=True)
    assert chain == ["bc.handover_up_error=0.05"]       # the chain teacher's hand-over stays, the sizes are the toy's
    wide = recipe_runner._overrides(dict(R.load("getup_keyframe").stage("rise_wide").config), toy=True)
    assert f"env.fallen.bank_starts={recipe_runner.TOY_BANK_STARTS}" in wide     # a wide fallen bank too
    assert recipe_runner.resolve_ref("@joystick/sharp", Path("/nowhere"), shipped=True).endswith(
        "policies/joystick/joystick.safetensors")
    with pytest.raises(FileNotFoundError, match="run `python -m training recipe joystick --stage sharp`"):
        recipe_runner.resolve_ref("@joystick/sharp", Path("/nowhere"))


def test_resume_on_a_fresh_machine_restores_the_campaign_before_choosing_stages(tmp_path, monkeypatch):
    """getup_keyframe keeps each member's stage (stand_still, rise_handover, roll_prone), the stages their start
    banks or other recipes read and its stage-1 DAgger campaign: on a fresh runs root --resume restores them, so
    complete stages and the stages they started from are not trained again (the kept campaign is complete)."""
    ran = []
    monkeypatch.setattr(recipe_runner, "_run_stage", lambda recipe, s, *a, **k: ran.append(s.name))
    assert recipe_runner.run("getup_keyframe", root=tmp_path, resume=True, progress=False)
    for kept in ("stand_still", "rise_handover", "rise_energy", "rise_retry", "roll_prone", "rise_rolled", "roll_side"):
        assert (tmp_path / "getup_keyframe" / kept).is_dir(), kept
    assert (tmp_path / "getup_keyframe" / "dagger" / "data").is_dir()
    assert ran == []
    # a later stage reads a restored stage's artifact: the campaign keeps no export, so its newest checkpoint is one
    artifact = Path(recipe_runner.resolve_ref("@getup_keyframe/rise_rolled", tmp_path))
    manifest = read_artifact(artifact)[3]
    assert artifact.parent == tmp_path / "getup_keyframe" / "rise_rolled" and manifest["trained"]
    assert manifest["provenance"]["steps"] == checkpoints.checkpoint_steps(artifact.parent)


def test_a_kept_run_state_names_other_stages_by_their_kept_runs(tmp_path):
    """A setting that names another stage's file under runs/ (a start bank's policy, a teacher; of this recipe or
    another) names that stage's kept run in the campaign, repository-relative: runs/ is not on another clone;
    settings outside runs/ stay."""
    runs, kept = tmp_path / "runs" / "getup_keyframe", checkpoints.REPO_ROOT / "training" / "campaigns"
    state = tmp_path / "run_state.json"
    state.write_text(json.dumps({"env_config": {"rolled_starts": {"roll_policy": f"{runs}/roll_side/a.safetensors"},
                                                "upright": "policies/joystick/joystick.safetensors"},
                                 "ppo_config": {"teacher": {"stand": "runs/getup_keyframe/stand/s.safetensors",
                                                            "bc_weight": 3.0}},
                                 "init": f"{runs}/rise/checkpoints/000000000010"}))
    campaign._refer_to_campaign(state, runs.parent, kept)
    saved = json.loads(state.read_text())
    assert saved["env_config"]["rolled_starts"]["roll_policy"] == "training/campaigns/getup_keyframe/roll_side"
    campaign._refer_to_campaign(state, checkpoints.REPO_ROOT / "runs", kept)
    teacher = json.loads(state.read_text())["ppo_config"]["teacher"]
    assert teacher == {"stand": "training/campaigns/getup_keyframe/stand", "bc_weight": 3.0}   # repository-relative
    assert saved["env_config"]["upright"] == "policies/joystick/joystick.safetensors"
    assert saved["init"] == f"{runs}/rise/checkpoints/000000000010"      # provenance, as it ran
