"""DAgger with the planner as the expert (training/imitation/) on a tiny case: the takeover labels, their
reproducibility, the data set on disk, the learner's export and the CLI's errors."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from common import events
from common import observation as obsdef
from training.evaluation.artifact_policy import ArtifactPolicy
from training.imitation import __main__ as cli
from training.imitation import best_of_k, config, coverage, dagger, dataset, expert
from training.imitation.campaign import build
from training.imitation.learner import fit, load_learner, new_learner

TINY = ["expert.policy_samples=2", "expert.plan_samples=2", "expert.horizon_s=0.2", "fit.steps=16",
        "fit.batch_size=64"]


@pytest.fixture(scope="module")
def tiny():
    cfg, teacher, env = build(TINY)
    obs, q = dataset.demonstration_pairs(dagger.DEFAULT_DEMOS)
    p = teacher.p
    learner = new_learner(obs[:512], list(cfg.fit.hidden_layer_sizes), 0, env.manifest_fields(), p.lo, p.hi)
    return cfg, teacher, env, learner, (obs[:512], q[:512])


def _starts(env, n, seed):
    return (a.astype(np.float64) for a in env.fallen_starts(n, seed))


def test_a_round_labels_every_takeover_step_reproducibly_from_its_seed(tiny):
    cfg, teacher, env, learner, _ = tiny
    qpos, qvel = _starts(env, 2, 5)
    p = teacher.p
    seg = int(cfg.expert.takeover_replans) * p.replan_knots * p.spk
    a, b = (dagger.collect(teacher, learner, qpos, qvel, 0.5, seg * p.ctrl_dt, np.random.default_rng(3))
            for _ in range(2))
    c = dagger.collect(teacher, learner, qpos, qvel, 0.5, seg * p.ctrl_dt, np.random.default_rng(4))
    assert a["obs"].shape == (2 * seg, obsdef.observation_size(obsdef.TERMS_GETUP))
    assert a["q_des"].shape == (2 * seg, 23)
    assert np.array_equal(a["obs"], b["obs"]) and np.array_equal(a["q_des"], b["q_des"])
    assert not np.array_equal(a["q_des"], c["q_des"])
    assert np.all(a["q_des"] >= p.lo - 1e-5) and np.all(a["q_des"] <= p.hi + 1e-5)
    # the first label of each robot is at its start: the takeover begins where the learner is
    np.testing.assert_allclose(a["obs"][:2, -23:], qvel[:, 6:], atol=1e-4)
    assert a["cpu_s"] > 0 and a["met_gate"] == 0


def test_the_takeover_warm_starts_from_the_policy_and_moves_the_robots(tiny):
    cfg, teacher, env, learner, _ = tiny
    qpos, qvel = _starts(env, 2, 9)
    robots = expert.Robots(teacher.p.physics, 2)
    robots.b.qpos[:], robots.b.qvel[:], robots.b.time[:], robots.b.qacc_warmstart[:] = qpos, qvel, 0.0, 0.0
    robots.b.forward()
    proposal = teacher.proposal(robots, learner.targets)
    assert proposal.shape == (2, teacher.p.K, 23)
    np.testing.assert_allclose(proposal[:, 0], learner.targets(teacher.observe(robots)), atol=1e-6)
    np.testing.assert_allclose(robots.b.qpos, qpos)          # the proposal ran on a copy


def test_a_robot_that_fell_back_to_the_floor_starts_its_rise_over(tiny):
    cfg, teacher, env, _, _ = tiny
    qpos, qvel = _starts(env, 2, 9)
    robots, _, waypoint = teacher.start(qpos, qvel)
    assert np.all(teacher.p.readings(robots.b)["h"] < cfg.expert.restart_below_m)     # lying
    past = np.array([teacher.last_wp, 0])
    np.testing.assert_array_equal(teacher.advance_waypoints(robots, past), [0, 0])
    never = build([*TINY, "expert.restart_below_m=0"])[1]
    assert never.advance_waypoints(robots, past)[0] == teacher.last_wp


def test_the_teachers_own_rises_report_when_the_gate_held_reproducibly(tiny):
    cfg, teacher, env, learner, _ = tiny
    qpos, qvel = _starts(env, 2, 5)
    a, b = (coverage.rises(teacher, learner.targets, qpos, qvel, 0.4, np.random.default_rng(1)) for _ in range(2))
    assert a["gate_time_s"].shape == a["held_s"].shape == (2,)
    np.testing.assert_array_equal(a["held_s"], b["held_s"])
    assert np.all(np.isnan(a["gate_time_s"])) and np.all(a["held_s"] == 0)    # an untrained learner, 0.4 s
    gate_s, held_s = np.array([1.0, np.nan, 2.0, 3.0]), np.array([1.2, 0.0, 0.5, 1.0])
    out = coverage.summarise(gate_s, held_s, np.array(["face_down", "on_back", "on_back", "face_down"]))
    assert out["all"] == {"rises": 4, "met_gate": 3, "share": 0.75, "held": 0.667}
    assert out["on_back"] == {"rises": 2, "met_gate": 1, "share": 0.5, "held": 0.0} and "side" not in out
    assert events.longest_run(np.array([1, 1, 0, 1, 1, 1, 0], bool)) == 3


def test_best_of_k_labels_the_first_rise_that_meets_the_gate_up_to_it_and_the_hold(tiny):
    cfg, teacher, env, learner, _ = tiny
    from training.planner import demos as planner_demos
    demo = planner_demos.load(dagger.DEFAULT_DEMOS / "demo_1.npz")
    t = int(np.flatnonzero(demo.gate & demo.kneeling)[0])
    assert demo.gate_time_s is not None
    at_gate = (demo.qpos[t:t + 1].astype(np.float64), demo.qvel[t:t + 1].astype(np.float64))
    fallen = tuple(_starts(env, 1, 5))
    bok = cfg.expert.best_of_k.copy_and_resolve_references()
    bok.k = 3
    hold = lambda obs: np.repeat(demo.targets[t][None], len(obs), axis=0)      # noqa: E731  (keeps the kneel)
    got = best_of_k.collect(teacher, hold, *(np.concatenate(x) for x in zip(at_gate, fallen)), bok, 0.2,
                            np.random.default_rng(0))
    steps = round(0.2 / teacher.p.ctrl_dt)
    assert got["met_gate"] == got["policy_met_gate"] == 1          # from the kneel, by the policy itself
    assert 0 < got["gate_time_s"][0] <= 0.2 and np.isnan(got["gate_time_s"][1])    # the chosen rise's, per start
    assert 0 < got["held_s"][0] <= 0.2 and got["held_s"][1] == 0
    assert got["obs"].shape == (steps, 52)                          # the hold outlasts the rollout: every step
    np.testing.assert_allclose(got["q_des"], np.clip(hold(got["obs"]), teacher.p.lo, teacher.p.hi), atol=1e-6)
    bok.clean = True                                                # the kneel start never lay: no attempt failed
    clean = best_of_k.collect(teacher, hold, *(np.concatenate(x) for x in zip(at_gate, fallen)), bok, 0.2,
                              np.random.default_rng(0))
    assert clean["met_gate"] == 1
    np.testing.assert_array_equal(clean["q_des"], got["q_des"])
    dq = best_of_k.noise(np.random.default_rng(1), 4, 25, 23, 0.05, 5)
    assert dq.shape == (25, 4, 23) and 0.02 < dq.std() < 0.08
    np.testing.assert_allclose(dq[5], dq[4] + (dq[6] - dq[4]) / 2, atol=0.05)   # linear between knots


def test_a_clean_rise_is_one_without_a_failed_attempt_by_the_events_rule():
    up = np.ones(7)
    lying, rise, fall_back = 0.05, 0.05 + events.ATTEMPT_RISE_M + 0.05, 0.05
    assert best_of_k.failed_attempts(np.array([lying, 0.1, 0.2, 0.3, 0.35, 0.4, 0.41]), up, 0.02) == 0
    assert best_of_k.failed_attempts(np.array([lying, 0.1, rise, fall_back, 0.2, 0.3, 0.41]), up, 0.02) == 1
    # a dip smaller than the rule's is no failed attempt
    dip = rise - events.ATTEMPT_RISE_M + 0.02
    assert best_of_k.failed_attempts(np.array([lying, 0.1, rise, dip, 0.3, 0.35, 0.41]), up, 0.02) == 0


def test_the_coverage_cli_refuses_bad_input_naming_it(tmp_path, capsys):
    for bad, name in ((["--policy", str(tmp_path / "none.safetensors")], "--policy"),
                      (["--lying", "upside_down"], "--lying"), (["--seeds", "0"], "--seeds")):
        args = ["--policy", str(tmp_path / "none.safetensors"), "--out", str(tmp_path / "c.json"), *bad]
        assert coverage.main(args) == 2
        assert name in capsys.readouterr().err
    assert not (tmp_path / "c.json").exists()


def test_the_data_set_round_trips_compactly_and_refuses_corrupt_files(tmp_path):
    obs = np.random.default_rng(0).normal(size=(10, 52)).astype(np.float32)
    q = np.random.default_rng(1).uniform(-1, 1, size=(10, 23)).astype(np.float32)
    path = dataset.save_round(tmp_path, 1, obs, q)
    back_obs, back_q = dataset.load_round(tmp_path, 1)
    np.testing.assert_allclose(back_obs, obs, atol=5e-3)
    np.testing.assert_allclose(back_q, q, atol=1e-3)
    assert np.load(path)["obs"].dtype == np.float16
    dataset.save_round(tmp_path, 2, obs[:4], q[:4])
    assert len(dataset.aggregate(tmp_path, dagger.DEFAULT_DEMOS, 3, first=2)[0]) == 4    # one expert's rounds only
    with pytest.raises(ValueError, match="no rounds from 3 on"):
        dataset.aggregate(tmp_path, dagger.DEFAULT_DEMOS, 3, first=3)
    path.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="round_01.npz"):
        dataset.load_round(tmp_path, 1)
    with pytest.raises(ValueError, match="finite"):
        dataset.save_round(tmp_path, 2, obs * np.nan, q)


def test_the_fitted_learner_exports_as_the_artifact_the_runtime_runs(tiny, tmp_path):
    cfg, teacher, env, learner, (obs, q) = tiny
    fitted, loss = fit(learner, obs, learner.label_actions(q), cfg.fit, 0)
    assert len(loss) == 2 and loss[1] < loss[0]
    fitted.export(tmp_path / "k.safetensors", dagger.manifest(env.manifest_fields(), len(obs), 0, 0.0))
    again = load_learner(tmp_path / "k.safetensors", learner)         # the artifact is the learner's checkpoint
    np.testing.assert_allclose(again.actions(obs[:8]), fitted.actions(obs[:8]), atol=1e-6)
    art = ArtifactPolicy.load(tmp_path / "k.safetensors")
    art.check_env(env)
    assert art.trained and art.manifest["obs_terms"] == [list(t) for t in obsdef.TERMS_GETUP]
    layers, mean, std = art.params
    ours = obsdef.policy_forward(layers, obs[:8], mean, std, art.manifest["activation"], art.manifest["output_rule"])
    np.testing.assert_allclose(ours, fitted.actions(obs[:8]), atol=1e-5)


def test_a_policy_of_another_network_or_action_map_is_refused_as_the_learner(tiny, tmp_path):
    cfg, teacher, env, learner, (obs, _) = tiny
    p = teacher.p
    fields = env.manifest_fields()
    small = new_learner(obs, [32, 16], 0, fields, p.lo, p.hi)
    small.export(tmp_path / "small.safetensors", dagger.manifest(fields, 0, 0, 0.0))
    with pytest.raises(ValueError, match="layers"):
        load_learner(tmp_path / "small.safetensors", learner)
    learner.export(tmp_path / "scaled.safetensors", dagger.manifest({**fields, "action_scale": 1.0}, 0, 0, 0.0))
    with pytest.raises(ValueError, match="action_scale"):
        load_learner(tmp_path / "scaled.safetensors", learner)


def test_a_round_rolled_out_by_another_policy_keeps_it_beside_its_data(tiny, tmp_path):
    cfg, teacher, _, _, _ = tiny
    policy = tmp_path / "ppo.safetensors"
    policy.write_bytes(b"an artifact's bytes")
    camp = dagger.Campaign(tmp_path / "camp", cfg, teacher.p.cfg)
    got = {"obs": np.zeros((3, 52)), "q_des": np.zeros((3, 23)), "met_gate": 1, "cpu_s": 0.3}
    stats = camp.store_round(1, got, 2, policy)
    kept = dataset.policy_path(camp.data, 1)
    assert kept.read_bytes() == policy.read_bytes() and stats["policy"].endswith(kept.name)
    assert stats["policy_from"] == str(policy) and stats["labels"] == 3
    assert "policy" not in camp.store_round(2, got, 2)
    again = camp.store_round(3, got, 2, policy)           # a later round by the same policy keeps it once
    assert again["policy"] == stats["policy"] and not dataset.policy_path(camp.data, 3).exists()
    rolled = camp.store_round(4, got, 2, policy, rolled_by=policy)    # the roll its starts came from, named
    assert rolled["rolled_by"] == str(policy) and "lying" not in rolled


def test_a_round_from_one_lying_side_starts_only_from_starts_lying_that_way(tiny):
    _, _, env, _, _ = tiny
    from training.planner.demos import start_side
    qpos, qvel = dagger.round_starts(env, 3, 100, "on_back")
    assert qpos.shape[0] == qvel.shape[0] == 3 and {start_side(q) for q in qpos} == {"on_back"}
    both, _ = env.fallen_starts(dagger.LYING_DRAWS * 3, 100)      # the first of the round's seeds that lie so
    on_back = [q for q in both if start_side(q) == "on_back"][:3]
    np.testing.assert_array_equal(qpos, np.asarray(on_back))


@pytest.mark.slow
def test_a_round_rolled_by_a_roll_starts_face_down_where_that_roll_hands_over(tiny):
    _, _, env, _, _ = tiny
    from common import model as t1model
    roll = sorted(Path("training/campaigns/getup_keyframe/roll_prone/checkpoints").glob("*"))[-1]
    qpos, qvel = dagger.round_starts(env, 4, 100, rolled_by=roll)
    assert 1 <= len(qpos) <= 4 and qvel.shape == (len(qpos), env.mj_model.nv)
    assert np.all(t1model.trunk_forward_z(qpos) < -events.ROLLED_FORWARD_Z)        # the rise's hand-over
    assert np.all(np.linalg.norm(qvel[:, 3:6], axis=1) < events.ROLLED_MAX_ANG_SPEED_RAD_S)
    fallen, _ = env.fallen_starts(dagger.ROLLED_DRAWS * 4, 100)
    assert not any(np.allclose(q, f) for q in qpos for f in fallen)                # rolled, not the falls


def test_a_campaign_is_given_more_rounds_but_refuses_other_fit_settings(tiny, tmp_path):
    cfg, teacher, *_ = tiny
    dagger.Campaign(tmp_path, cfg, teacher.p.cfg).finish_round(
        {"round": 0, "labels_total": 0, "reached_kneel": 0.0, "face_down": 0.0, "on_back": 0.0})
    more = build([*TINY, f"rounds={int(cfg.rounds) + 1}"])[0]
    assert dagger.Campaign(tmp_path, more, teacher.p.cfg).next_round == 1
    other = build([*TINY, f"rounds={int(cfg.rounds) + 1}", "fit.steps=17"])[0]
    with pytest.raises(ValueError, match="other settings"):
        dagger.Campaign(tmp_path, other, teacher.p.cfg)


def test_each_round_records_its_expert_and_a_later_round_may_change_it(tiny, tmp_path):
    cfg, teacher, *_ = tiny
    got = {"obs": np.zeros((3, 52)), "q_des": np.zeros((3, 23)), "met_gate": 0, "cpu_s": 0.3}
    camp = dagger.Campaign(tmp_path, cfg, teacher.p.cfg)
    assert camp.store_round(1, got, 2)["expert"] == cfg.expert.to_dict()
    older = json.loads((camp.data / config.COLLECTED).read_text())     # a folder from before rounds kept theirs
    older["config"]["dagger"]["expert"] = older["rounds"]["1"].pop("expert")
    (camp.data / config.COLLECTED).write_text(json.dumps(older))
    later = build([*TINY, "expert.restart_below_m=0.3"])[0]
    camp = dagger.Campaign(tmp_path, later, teacher.p.cfg)
    assert camp.collected_round(1)["expert"] == cfg.expert.to_dict()
    assert camp.store_round(2, got, 2)["expert"]["restart_below_m"] == 0.3
    with pytest.raises(ValueError, match="collected with other settings"):
        dagger.Campaign(tmp_path, build([*TINY, "starts_per_round=5"])[0], teacher.p.cfg)


def test_bad_input_is_refused_naming_the_problem(tmp_path, capsys):
    assert cli.main(["--out", str(tmp_path), "--rounds", "0"]) == 2
    assert "--rounds" in capsys.readouterr().err
    assert cli.main(["--out", str(tmp_path), "--config", "no_such_knob=1"]) == 2
    assert "no_such_knob" in capsys.readouterr().err
    assert cli.main(["--out", str(tmp_path), "--demos", str(tmp_path / "none"), *sum(
        (["--config", o] for o in TINY), [])]) == 2
    assert "no planner demonstrations" in capsys.readouterr().err
    assert cli.main(["--out", str(tmp_path / "fresh"), "--policy", str(tmp_path / "any.safetensors"), *sum(
        (["--config", o] for o in TINY), [])]) == 2
    assert "--policy" in capsys.readouterr().err           # round 0 fits the demonstrations: nothing rolls out
    for bad in (["--lying", "upside_down"], ["--lying", "on_back"]):    # not a side; round 0 rolls nothing out
        assert cli.main(["--out", str(tmp_path / "fresh"), *bad, *sum((["--config", o] for o in TINY), [])]) == 2
        assert "--lying" in capsys.readouterr().err
    assert cli.main(["--out", str(tmp_path / "fresh"), "--rolled-by", str(tmp_path / "roll.safetensors"), *sum(
        (["--config", o] for o in TINY), [])]) == 2
    assert "--rolled-by" in capsys.readouterr().err         # round 0 rolls nothing out
    cfg, teacher, _ = build(TINY)
    dagger.Campaign(tmp_path / "begun", cfg, teacher.p.cfg).finish_round(
        {"round": 0, "labels_total": 0, "reached_kneel": 0.0, "face_down": 0.0, "on_back": 0.0})
    assert cli.main(["--out", str(tmp_path / "begun"), "--lying", "on_back", "--rolled-by", str(tmp_path / "r"),
                     *sum((["--config", o] for o in TINY), [])]) == 2
    assert "two sources of a round's starts" in capsys.readouterr().err
