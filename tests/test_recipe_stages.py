"""A recipe stage that ends at a named earlier checkpoint (end_at), and imitation stages that continue one DAgger
campaign between PPO stages (continues / policy / lying / the expert's config): completion, what later stages
start from, what the campaign keeps, and the arguments each round is run with. No training here (the toy run of
every recipe is tests/test_recipes.py's)."""
from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest

from training.core import checkpoints
from training.imitation import campaign as imitation
from training.imitation import config as imitation_config
from training.recipes import base as R
from training.recipes import campaign
from training.recipes import runner as recipe_runner

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "training" / "campaigns" / "getup_keyframe"


def _ppo_run(root: Path, recipe: str, stage: str, steps: list[int], state: dict) -> Path:
    run = root / recipe / stage
    for n in steps:
        checkpoints.checkpoint_path(run, n).mkdir(parents=True)
    (run / checkpoints.RUN_STATE).write_text(json.dumps({"preset": "cpu", **state}))
    return run


def _two_stages() -> R.Recipe:
    return R.Recipe("r", "r", "", (R.Stage("long", task="getup_kneel", steps=300, end_at=100),
                                   R.Stage("next", task="getup_kneel", steps=10, init="long")))


def test_a_stage_ends_at_its_end_at_checkpoint_however_far_its_run_went(tmp_path, monkeypatch):
    recipe = _two_stages()
    long = recipe.stage("long")
    run = _ppo_run(tmp_path, "r", "long", [50], {"env_steps": 50, "target_steps": 300})
    assert not recipe_runner.stage_complete(tmp_path, recipe, long)
    with pytest.raises(FileNotFoundError, match="no checkpoint at its end_at"):
        recipe_runner._init_path("long", recipe, tmp_path)
    for n in (100, 200, 300):     # the run went on to its target: the stage still ends at 100
        checkpoints.checkpoint_path(run, n).mkdir(parents=True)
    (run / checkpoints.RUN_STATE).write_text(json.dumps({"preset": "cpu", "env_steps": 300, "target_steps": 300}))
    assert recipe_runner.stage_complete(tmp_path, recipe, long)
    assert recipe_runner._init_path("long", recipe, tmp_path) == checkpoints.checkpoint_path(run, 100)
    # a toy run ends at its toy end
    toy = _ppo_run(tmp_path / "toy", "r", "long", [recipe_runner.TOY_END_AT_STEPS[1]],
                   {"env_steps": 80, "target_steps": 160, "preset": "toy"})
    assert recipe_runner.end_checkpoint(toy, long).name == f"{recipe_runner.TOY_END_AT_STEPS[1]:012d}"
    # the campaign keeps the checkpoint the stage ended at, not the run's newest
    monkeypatch.setattr(R, "load", lambda name: recipe)
    monkeypatch.setattr(R, "names", lambda: ["r"])
    recipe_runner.save_campaign("r", tmp_path, tmp_path / "campaigns")
    kept = tmp_path / "campaigns" / "r" / "long" / checkpoints.CHECKPOINT_DIR
    assert [p.name for p in kept.iterdir()] == [f"{100:012d}"]
    # a chain's evaluation report kept beside the run's files stays when the campaign is saved again
    (kept.parent / "chain_report.md").write_text("1000 seeds")
    (run / "chain_report.md").write_text("an older report in the run")     # not one of the files a save copies
    recipe_runner.save_campaign("r", tmp_path, tmp_path / "campaigns")
    assert (kept.parent / "chain_report.md").read_text() == "1000 seeds" and kept.is_dir()
    fresh = tmp_path / "fresh"
    recipe_runner.restore_campaign(recipe, long, fresh, tmp_path / "campaigns")
    assert recipe_runner.stage_complete(fresh, recipe, long)
    assert recipe_runner._init_path("long", recipe, fresh) == checkpoints.checkpoint_path(fresh / "r" / "long", 100)


def test_a_run_keeps_its_end_checkpoint_while_it_prunes_the_others(tmp_path, monkeypatch):
    from brax.training import checkpoint as brax_checkpoint
    monkeypatch.setattr(brax_checkpoint, "save", lambda root, step, *a: (Path(root) / f"{step:012d}").mkdir(
        parents=True))
    for n in range(1, 7):
        checkpoints.save_checkpoint(tmp_path, 100 * n, (), None, end_at=150)
    assert [int(p.name) for p in checkpoints.list_checkpoints(tmp_path)] == [200, 400, 500, 600]
    assert checkpoints.end_checkpoint(tmp_path, 150).name == f"{200:012d}"
    assert checkpoints.end_checkpoint(tmp_path, 700) is None


def test_end_at_is_a_ppo_stages_checkpoint_or_a_distill_stages_phase_within_its_steps():
    with pytest.raises(ValueError, match="end_at is a PPO stage's checkpoint"):
        R.Recipe("x", "x", "", (R.Stage("a", task="getup", steps=100, end_at=200),))
    chain = {"roll": "@r/a", "rise": "@r/b", "stand": "@r/c"}
    with pytest.raises(ValueError, match="or a distill stage's phase"):
        R.Recipe("x", "x", "", (R.Stage("a", kind="distill", task="getup", steps=400, end_at=500, teacher=chain),))
    R.Recipe("x", "x", "", (R.Stage("a", kind="distill", task="getup", steps=400, end_at=300, teacher=chain),))
    with pytest.raises(ValueError, match="end_at is a PPO stage's checkpoint"):
        R.Recipe("x", "x", "", (R.Stage("a", kind="imitation", steps=3, end_at=2),))
    with pytest.raises(ValueError, match="init_artifact is a PPO stage's with an init"):
        R.Recipe("x", "x", "", (R.Stage("a", task="getup", steps=100, init_artifact=True),))
    for kind, teacher in (("imitation", {}), ("distill", chain)):
        with pytest.raises(ValueError, match="init_artifact is a PPO stage's with an init"):
            R.Recipe("x", "x", "", (R.Stage("a", task="getup", steps=100),
                                    R.Stage("b", kind=kind, task="getup", steps=1, init="a", init_artifact=True,
                                            teacher=teacher)))
    R.Recipe("x", "x", "", (R.Stage("a", task="getup", steps=100),
                            R.Stage("b", task="getup", steps=10, init="a", init_artifact=True)))


def test_the_campaign_keeps_no_stage_that_saving_it_would_drop():
    """Each stage folder in campaigns/getup_keyframe is still needed: no complete later stage starts from it
    through its inits, or a config names it (save_campaign's rule). rise_best, say, went once rise_rolled,
    which started from it, was complete."""
    recipe = R.load("getup_keyframe")
    for folder in sorted(p for p in CAMPAIGN.iterdir() if p.is_dir() and p.name != "demos"):
        stage = recipe.stage(folder.name.split(".")[0])
        assert not campaign.droppable(CAMPAIGN.parent, recipe, stage), f"{folder.name} is superseded"
    assert campaign.droppable(CAMPAIGN.parent, recipe, recipe.stage("rise_best"))


def _distill_run(root: Path, recipe: str, stage: str, phases: list[int], state: dict) -> Path:
    run = root / recipe / stage
    for n in phases:
        checkpoints.checkpoint_path(run, n).mkdir(parents=True)
    (run / recipe_runner.DISTILL_STATE).write_text(json.dumps(state))
    return run


def test_a_distill_stage_ends_at_its_phase_and_the_next_stage_starts_from_there(tmp_path, monkeypatch):
    """A distill stage's run stops, finished, at end_at (dagger.distill's end_at); a run stopped by --max-minutes
    before it goes on to the same phase of the campaign; the next stage starts from the run's newest checkpoint."""
    from training.distill import dagger
    chain = {"roll": "r", "rise": "s", "stand": "t"}
    recipe = R.Recipe("r", "r", "", (R.Stage("d", kind="distill", task="getup", steps=400, end_at=300, teacher=chain,
                                             config={"bc.num_evals": 5}),
                                     R.Stage("e", kind="distill", task="getup", steps=10, init="d", teacher=chain)))
    calls = []

    def distill(teacher, out, **kw):
        if kw["end_at"] is not None:      # the run checkpoints its end phase
            dagger.check_end_at(kw["end_at"], dagger.dagger_configs("getup", "gpu", kw["overrides"], None, False)[0])
        calls.append((Path(out).name, kw))
    monkeypatch.setattr(dagger, "distill", distill)
    run = functools.partial(recipe_runner._run_stage, recipe, recipe.stage("d"), tmp_path, max_minutes=None,
                            backend="cpu", progress=False, provenance={"sha256": "0" * 64})
    run(resume=False, toy=False)
    assert calls[-1][1]["end_at"] == 300 and "bc.dagger_steps=400" in calls[-1][1]["overrides"]
    run(resume=False, toy=True)
    assert calls[-1][1]["end_at"] is None                 # a toy run's few phases end at their last
    _distill_run(tmp_path, "r", "d", [0, 100], {"phases": 100, "finished": True, "stopped_by_max_minutes": True})
    run(resume=True, toy=False)                           # stopped at phase 100: 200 more, of 300 left
    assert calls[-1][0] == "d.2" and calls[-1][1]["end_at"] == 200
    assert "bc.dagger_steps=300" in calls[-1][1]["overrides"]
    assert not recipe_runner.stage_complete(tmp_path, recipe, recipe.stage("d"))
    _distill_run(tmp_path, "r", "d.2", [0, 200], {"phases": 300, "finished": True, "end_at": 200})
    assert recipe_runner.stage_complete(tmp_path, recipe, recipe.stage("d"))
    assert recipe_runner._init_path("d", recipe, tmp_path) == tmp_path / "r" / "d.2"


def test_a_resumed_distill_stage_checkpoints_as_often_as_the_stage_itself():
    assert recipe_runner.resumed_evals(2600, 3400, 35) == 26        # every 100 phases, as its first run did
    assert recipe_runner.resumed_evals(300, 400, 5) == 3
    assert recipe_runner.resumed_evals(250, 400, 5) == 2            # never more often than every 100
    assert recipe_runner.resumed_evals(7, 400, 5) == 1


def test_a_distill_run_ends_only_at_a_phase_it_checkpoints():
    from training.distill import dagger
    cfg = dagger.dagger_configs("getup", "gpu", ["bc.dagger_steps=400", "bc.num_evals=5"], None,
                                union_terms=False)[0]
    dagger.check_end_at(300, cfg)
    for bad in (250, 0, 500):
        with pytest.raises(ValueError, match=f"end_at {bad} is not a checkpointed phase .*multiple of 100"):
            dagger.check_end_at(bad, cfg)


# ---------------------------------------------------------------- imitation stages between PPO stages
def test_imitation_stages_continue_one_campaign_and_are_complete_at_their_rounds(tmp_path):
    recipe = R.load("getup_keyframe")
    rounds = [s for s in recipe.stages if s.kind == "imitation"]
    assert [s.name for s in rounds] == ["dagger", "dagger_explore", "dagger_fine", "dagger_back", "dagger_best",
                                       "dagger_clean", "dagger_handover"]
    assert [recipe.rounds_through(s) for s in rounds] == [7, 8, 9, 12, 15, 19, 23]
    folder = tmp_path / "getup_keyframe" / "dagger"
    assert all(recipe_runner.stage_dirs(tmp_path, recipe, s) == [] for s in rounds)
    folder.mkdir(parents=True)
    (folder / imitation_config.STATE).write_text(json.dumps({"config": {}, "rounds": [{}] * 9}))
    assert all(recipe_runner.stage_dirs(tmp_path, recipe, s) == [folder] for s in rounds)
    assert [recipe_runner.stage_complete(tmp_path, recipe, s) for s in rounds] == [True, True, True, False, False,
                                                                                   False, False]


def test_the_campaigns_rounds_were_made_as_the_recipe_says():
    """Each round of the kept DAgger campaign was rolled out by its stage's policy (or the learner), from the
    stage's lying side or its roll's hand-overs, with its expert (the planner's takeovers or best-of-K); the
    rounds the campaign keeps so far."""
    recipe = R.load("getup_keyframe")
    rows = json.loads((CAMPAIGN / "dagger" / imitation_config.STATE).read_text())["rounds"]
    collected = json.loads((CAMPAIGN / "dagger" / "data" / imitation_config.COLLECTED).read_text())["rounds"]
    for s in (s for s in recipe.stages if s.kind == "imitation"):
        for k in range(recipe.rounds_through(s) - s.steps, recipe.rounds_through(s)):
            if k == 0 or k >= len(rows):
                continue          # the demonstrations' fit; a round still to run
            row, stats = rows[k], collected[str(k)]
            assert bool(row.get("policy")) == bool(s.policy), (s.name, k)
            assert row.get("lying", "") == s.lying, (s.name, k)
            assert bool(row.get("rolled_by")) == bool(s.rolled_by), (s.name, k)
            best_of_k = stats["expert"].get("best_of_k", {"k": 0})
            assert best_of_k["k"] == s.config.get("dagger.expert.best_of_k.k", 0), (s.name, k)
            if best_of_k["k"]:
                assert best_of_k["sigma_rad"] == s.config["dagger.expert.best_of_k.sigma_rad"]
            assert stats["expert"].get("restart_below_m", 0.0) == s.config.get(
                "dagger.expert.restart_below_m", 0.25), (s.name, k)


def _recorded_rounds(monkeypatch) -> list[dict]:
    """imitation.run replaced by one that records its arguments and adds the rounds it was asked for."""
    calls = []

    def run(out, overrides, demos=None, rounds=None, max_minutes=None, eval_dir=None, refit=False, policy=None,
            lying="", rolled_by=None):
        calls.append({"rounds": rounds, "policy": policy, "lying": lying, "rolled_by": rolled_by,
                      "overrides": list(overrides)})
        state = json.loads((Path(out) / imitation_config.STATE).read_text())
        state["rounds"] += [{}] * (rounds - len(state["rounds"]))
        (Path(out) / imitation_config.STATE).write_text(json.dumps(state))
        return state

    monkeypatch.setattr(imitation, "run", run)
    return calls


def _run(recipe, name, root, resume=False):
    recipe_runner._run_stage(recipe, recipe.stage(name), root, resume=resume, max_minutes=None, backend=None,
                             toy=False, progress=False, provenance={"sha256": "0" * 64})


def test_interleaved_imitation_stages_roll_each_round_out_by_their_policy(tmp_path, monkeypatch):
    calls = _recorded_rounds(monkeypatch)
    recipe = R.load("getup_keyframe")
    folder = tmp_path / "getup_keyframe" / "dagger"
    folder.mkdir(parents=True)
    (folder / imitation_config.STATE).write_text(json.dumps({"config": {}, "rounds": [{}] * 8}))
    with pytest.raises(FileNotFoundError, match="continues from round 9"):
        _run(recipe, "dagger_back", tmp_path)
    slow = tmp_path / "getup_keyframe" / "rise_slow"
    wide = tmp_path / "getup_keyframe" / "rise_wide"
    for run in (slow, wide):
        run.mkdir()
    state = json.loads((folder / imitation_config.STATE).read_text())
    (folder / imitation_config.STATE).write_text(json.dumps({**state, "rounds": [{}] * 9}))
    _run(recipe, "dagger_back", tmp_path)
    artifact = slow / "getup_keyframe_rise_slow.safetensors"
    assert [c["rounds"] for c in calls] == [10, 11, 12]          # one call per round: each rolled out by it
    assert all(c["policy"] == artifact and c["lying"] == "on_back" for c in calls)
    assert all({"dagger.expert.restart_below_m=0.0", "dagger.rounds=12"} <= set(c["overrides"]) for c in calls)
    assert recipe_runner.stage_complete(tmp_path, recipe, recipe.stage("dagger_back"))
    calls.clear()
    _run(recipe, "dagger_best", tmp_path)
    assert [c["rounds"] for c in calls] == [13, 14, 15]
    assert all(c["policy"] == wide / "getup_keyframe_rise_wide.safetensors" and c["lying"] == "on_back"
               for c in calls)
    assert all({"dagger.expert.best_of_k.k=32", "dagger.expert.best_of_k.sigma_rad=0.05", "dagger.rounds=15"}
               <= set(c["overrides"]) for c in calls)
    assert not any(o.startswith("dagger.expert.restart_below_m") for o in calls[0]["overrides"])
    # a stage whose rounds were begun goes on only with --resume
    (folder / imitation_config.STATE).write_text(json.dumps({**state, "rounds": [{}] * 13}))
    with pytest.raises(FileExistsError, match="pass --resume"):
        _run(recipe, "dagger_best", tmp_path)
    calls.clear()
    _run(recipe, "dagger_best", tmp_path, resume=True)
    assert [c["rounds"] for c in calls] == [14, 15]


def test_a_stage_rolled_by_a_roll_starts_each_round_at_that_rolls_hand_overs(tmp_path, monkeypatch):
    calls = _recorded_rounds(monkeypatch)
    recipe = R.load("getup_keyframe")
    folder = tmp_path / "getup_keyframe" / "dagger"
    folder.mkdir(parents=True)
    (folder / imitation_config.STATE).write_text(json.dumps({"config": {}, "rounds": [{}] * 19}))
    for name in ("rise_clean", "roll_prone"):
        (tmp_path / "getup_keyframe" / name).mkdir()
    _run(recipe, "dagger_handover", tmp_path)
    assert [c["rounds"] for c in calls] == [20, 21, 22, 23]
    roll = tmp_path / "getup_keyframe" / "roll_prone" / "getup_keyframe_roll_prone.safetensors"
    rise = tmp_path / "getup_keyframe" / "rise_clean" / "getup_keyframe_rise_clean.safetensors"
    assert all(c["rolled_by"] == roll and c["policy"] == rise and c["lying"] == "" for c in calls)
    assert all("dagger.expert.best_of_k.clean=True" in c["overrides"] for c in calls)


def test_the_first_imitation_stage_runs_its_rounds_in_one_call(tmp_path, monkeypatch):
    calls = _recorded_rounds(monkeypatch)
    recipe = R.load("getup_keyframe")
    folder = tmp_path / "getup_keyframe" / "dagger"
    folder.mkdir(parents=True)
    (folder / imitation_config.STATE).write_text(json.dumps({"config": {}, "rounds": []}))
    _run(recipe, "dagger", tmp_path)
    assert [(c["rounds"], c["policy"], c["lying"]) for c in calls] == [(7, None, "")]
    assert "dagger.rounds=7" in calls[0]["overrides"]


def test_imitation_stage_settings_are_checked():
    dagger = R.Stage("d", kind="imitation", steps=2)
    ppo = R.Stage("p", task="getup_kneel", steps=10, init="d")
    with pytest.raises(ValueError, match="continues 'p' is not an earlier imitation stage"):
        R.Recipe("x", "x", "", (dagger, ppo, R.Stage("e", kind="imitation", steps=1, continues="p")))
    with pytest.raises(ValueError, match="policy, lying and rolled_by take over rounds after the first"):
        R.Recipe("x", "x", "", (dagger, ppo, R.Stage("e", kind="imitation", steps=1, policy="p")))
    with pytest.raises(ValueError, match="policy 'later' is not an earlier stage"):
        R.Recipe("x", "x", "", (dagger, R.Stage("e", kind="imitation", steps=1, continues="d", policy="later")))
    with pytest.raises(ValueError, match="lying must be one of face_down, on_back, side"):
        R.Recipe("x", "x", "", (dagger, R.Stage("e", kind="imitation", steps=1, continues="d", lying="up")))
    with pytest.raises(ValueError, match="continues, policy, lying and rolled_by are an imitation stage's"):
        R.Recipe("x", "x", "", (dagger, R.Stage("q", task="getup_kneel", steps=10, lying="on_back")))
    with pytest.raises(ValueError, match="rolled_by 'later' is not an earlier stage"):
        R.Recipe("x", "x", "", (dagger, R.Stage("e", kind="imitation", steps=1, continues="d", rolled_by="later")))
    with pytest.raises(ValueError, match="lying and rolled_by are two sources"):
        R.Recipe("x", "x", "", (dagger, ppo, R.Stage("e", kind="imitation", steps=1, continues="d", lying="side",
                                                     rolled_by="p")))
    ok = R.Recipe("x", "x", "", (dagger, ppo, R.Stage("e", kind="imitation", steps=3, continues="d", policy="p",
                                                      lying="on_back")))
    assert ok.campaign_stage(ok.stage("e")) is dagger and ok.rounds_through(ok.stage("e")) == 5


def test_a_stage_whose_artifact_rolls_out_rounds_still_to_run_is_not_superseded(tmp_path):
    recipe = R.load("getup_keyframe")
    _ppo_run(tmp_path, "getup_keyframe", "rise_best", [recipe.stage("rise_best").end_at],
             {"env_steps": 3_031_040, "target_steps": 3_031_040})
    folder = tmp_path / "getup_keyframe" / "dagger"
    folder.mkdir()
    for rounds, superseded in ((12, False), (15, True)):     # dagger_best's rounds are rolled out by rise_wide
        (folder / imitation_config.STATE).write_text(json.dumps({"config": {}, "rounds": [{}] * rounds}))
        assert recipe_runner.superseded(tmp_path, recipe, recipe.stage("rise_wide")) is superseded
        assert recipe_runner.superseded(tmp_path, recipe, recipe.stage("rise_slow"))
