"""`python -m sim_hil.eval` end to end: every scenario runs one short seeded trial of the shipped untrained
student and of a baseline composite (untrained getup + joystick placeholders, t1-runtime --policy-upright)
in lockstep, and writes all three report parts (report.md, plots.png, video.mp4) plus results.json.
Untrained policies: this proves the plumbing and that the report refuses to claim a result."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from common import observation as obsdef
from common.artifact import write_artifact
from common.golden import base_manifest, random_policy
from sim_hil.eval import plans
from sim_hil.eval.plans import PUSH_AT_S
from sim_hil.launch import ROOT, _env

STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
SECONDS = {"getup": 3.0, "wall": 3.0, "puddle": 3.0, "push": PUSH_AT_S + 1.0}   # sim s; PREPARE takes 2 s
PLACEHOLDER_HIDDEN = (64, 64)


@pytest.fixture(scope="module")
def baseline(tmp_path_factory):
    """Untrained getup (getup obs terms) and joystick placeholders sharing the model's one gain set."""
    d = tmp_path_factory.mktemp("baseline")
    paths = []
    for i, (name, terms) in enumerate((("getup_untrained", obsdef.TERMS_GETUP),
                                       ("joystick_untrained", obsdef.TERMS_UNION))):
        layers, _, _ = random_policy(np.random.default_rng(10 + i), terms, PLACEHOLDER_HIDDEN)
        size = obsdef.observation_size(terms)
        manifest = base_manifest(name=name, trained=False, obs_terms=[list(t) for t in terms], provenance={
            "git_commit": "test", "steps": 0, "date": "test", "command": "tests/test_eval_hil.py (untrained)"})
        path = d / f"{name}.safetensors"
        write_artifact(path, layers, np.zeros(size, np.float32), np.ones(size, np.float32), manifest)
        paths.append(path)
    return paths


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["getup", "push", "wall", "puddle"])
def test_scenario_one_trial_writes_report(scenario, baseline, tmp_path, netns):
    out = tmp_path / scenario
    cmd = [sys.executable, "-m", "sim_hil.eval", scenario, "--policy", str(STUDENT),
           "--baseline", f"{baseline[0]},{baseline[1]}", "--trials", "1", "--seconds", str(SECONDS[scenario]),
           "--out", str(out)]
    run = subprocess.run(cmd, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=150)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    for part in ("report.md", "plots.png", "video.mp4", "results.json"):
        assert (out / part).is_file() and (out / part).stat().st_size > 0, f"{part} missing"
    logs = sorted((out / "logs").glob("*.lcmlog"))      # one LCM log per trial (sim_hil/lcmlog)
    assert [p.name.split("_")[0] for p in logs] == ["baseline", "student"], logs
    report = (out / "report.md").read_text()
    # the trained flags are printed at the top and next to every table; no result is claimed
    assert report.count("UNTRAINED") >= 3 and "No result is claimed" in report
    assert "baseline getup: UNTRAINED" in report and "baseline joystick: UNTRAINED" in report
    results = json.loads((out / "results.json").read_text())
    assert set(results["rows"]) == {"student", "baseline"}
    assert len(results["trials"]) == 2
    for trial in results["trials"]:
        assert trial["policy_start_s"] is not None, f"{trial['controller']} never reached POLICY"
        assert trial["runtime_faults"] == "", trial["runtime_faults"]
    if scenario == "push":
        assert results["trials"][0]["spec"]["faults"].startswith("push:x=")


@pytest.mark.slow
def test_failed_recording_fails_its_trial_and_lists_no_video(baseline, tmp_path, netns):
    """No GL backend (glfw without a display): the recorded trial fails with a message that names --record,
    the other trial is still reported, and no video is claimed."""
    out = tmp_path / "push"
    env = {k: v for k, v in _env().items() if k not in ("DISPLAY", "PYOPENGL_PLATFORM")}
    env["MUJOCO_GL"] = "glfw"
    cmd = [sys.executable, "-m", "sim_hil.eval", "push", "--policy", str(STUDENT),
           "--baseline", f"{baseline[0]},{baseline[1]}", "--trials", "1", "--seconds", str(SECONDS["push"]),
           "--no-log", "--out", str(out)]
    run = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=150)
    assert run.returncode == 1, run.stdout[-3000:] + run.stderr[-3000:]
    assert "trial FAILED: student" in run.stderr and "--record" in run.stderr, run.stderr[-3000:]
    assert not (out / "video.mp4").exists() and "video" not in run.stdout
    assert [t["controller"] for t in json.loads((out / "results.json").read_text())["trials"]] == ["baseline"]


def test_fig51_is_the_seeds_figure_setup():
    plan = plans.PLANS["fig5.1"]
    [spec] = plan.specs(plan.default_trials, plan.default_seconds, plan.seed0)
    assert (spec.seed, spec.spawn, spec.command_vx_mps) == (62, "fallen:62", 0.4)
    assert spec.prepare_s == 2.0 and plan.side_by_side


def _lying_then_standing_log(n: int = 3000, policy_from: int = 100, up_from: int = 1000):
    """A scripted trial log (2 ms ticks): POLICY from tick policy_from, lying and sliding back, standing
    and walking at 0.4 m/s from tick up_from."""
    from t1 import joint_command_t

    from common import model as t1model
    from sim_hil.eval.metrics import TickLog
    log = TickLog(t1model.load_model(), n)
    log.t[:] = np.arange(n) * 0.002
    log.mode[policy_from:] = joint_command_t.MODE_POLICY
    log.trunk[:], log.up_z[:], log.fwd_vel[:] = 0.15, 0.1, -0.5
    log.trunk[up_from:], log.up_z[up_from:], log.fwd_vel[up_from:] = 0.66, 1.0, 0.4
    log.base_x[:] = np.linspace(0.0, 20.0, n)       # crosses every wall segment and the finish line
    return log


def test_fig51_forward_velocity_counts_only_once_standing():
    from sim_hil.eval.trial import summarise
    spec = plans.fig51_specs(1, 6.0, plans.FIG51_SEED)[0]
    row = plans.fig51_rows([summarise(spec, "student", _lying_then_standing_log(), None)])
    assert row["stood up"] == "1/1" and row["getup attempts"] == "1.00"
    assert row["forward velocity once standing [m/s]"] == "0.40"


def test_kneel_counts_the_gate_in_the_kneeling_posture_by_how_the_robot_lay():
    """Stage 1's loop figures from scripted logs: a face-down start that kneels at the gate 1.8 s into POLICY
    for 1.2 s, one on the back that reaches the gate's height and tilt but not on both knees (a crouch)."""
    from sim_hil.eval.trial import summarise
    spec = plans.getup_specs(1, 6.0, 0)[0]
    kneels = _lying_then_standing_log(up_from=3000)
    kneels.forward_z[:] = -0.9
    kneels.trunk[1000:1600], kneels.up_z[1000:1600], kneels.kneeling[1000:1600] = 0.4, 1.0, 1.0
    crouches = _lying_then_standing_log(up_from=3000)
    crouches.forward_z[:] = 0.9
    crouches.trunk[1000:1600], crouches.up_z[1000:1600] = 0.4, 1.0
    trials = [summarise(spec, "student", log, None) for log in (kneels, crouches)]
    assert [(t.lying, round(t.kneel_hold_s, 3)) for t in trials] == [("face_down", 1.2), ("on_back", 0.0)]
    assert trials[0].kneel_time_s == pytest.approx(1.8)
    row = plans.kneel_rows(trials)
    assert row["the gate in the kneeling posture"] == "1/2" and row["… face down"] == "1/1"
    assert row["… on the back"] == "0/1" and row["… held ≥ 1 s (of those)"] == "1/1"


@pytest.mark.parametrize("name", sorted(plans.PLANS))
def test_every_seed_figure_names_a_row_of_its_report(name):
    """The seed's figures are keyed by our row labels: a renamed row must not silently lose its seed value."""
    from common.seed_figures import SEED_FIGURES
    from sim_hil.eval.trial import summarise
    plan = plans.PLANS[name]
    log = _lying_then_standing_log()
    trials = [summarise(spec, "student", log, plan.finish_x_m, "", plan.segment_edges_x)
              for spec in plan.specs(3, 6.0, plan.seed0)]
    rows = plan.rows(trials)
    assert set(SEED_FIGURES.get(name, {})) <= set(rows), set(SEED_FIGURES.get(name, {})) - set(rows)
    assert all(isinstance(v, str) for t in trials for v in plan.trial_cells(t).values())


@pytest.mark.slow
def test_fig51_teacher_and_student_side_by_side(baseline, tmp_path, netns):
    """The untrained placeholders stand in for the experts: the plumbing, and a report that claims nothing."""
    out = tmp_path / "fig51"
    cmd = [sys.executable, "-m", "sim_hil.eval", "fig5.1", "--policy", str(STUDENT),
           "--teacher", f"{baseline[0]},{baseline[1]}", "--seconds", "2.5", "--no-video", "--out", str(out)]
    run = subprocess.run(cmd, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=150)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    results = json.loads((out / "results.json").read_text())
    assert set(results["rows"]) == {"student", "teacher"}
    assert {t["spec"]["seed"] for t in results["trials"]} == {62}
    assert all(t["policy_start_s"] is not None for t in results["trials"])
    report = (out / "report.md").read_text()
    assert "teacher getup: UNTRAINED" in report and "No result is claimed" in report
    assert "forward velocity once standing [m/s]" in report and (out / "plots.png").stat().st_size > 0


def test_fig51_teacher_defaults_to_the_one_the_student_names(baseline, tmp_path):
    from sim_hil.eval.__main__ import distilled_from, parse_args
    layers, _, _ = random_policy(np.random.default_rng(3), obsdef.TERMS_UNION, PLACEHOLDER_HIDDEN)
    size = obsdef.observation_size(obsdef.TERMS_UNION)
    student = tmp_path / "student.safetensors"
    provenance = {"git_commit": "test", "steps": 0, "date": "test", "command": "test",
                  "teacher": {"getup": str(baseline[0]), "joystick": "policies/joystick/joystick.safetensors"}}
    write_artifact(student, layers, np.zeros(size, np.float32), np.ones(size, np.float32),
                   base_manifest(name="student", trained=False, obs_terms=[list(t) for t in obsdef.TERMS_UNION],
                                 provenance=provenance))
    want = f"{baseline[0]},{ROOT / 'policies' / 'joystick' / 'joystick.safetensors'}"
    assert distilled_from(student) == want       # relative paths are the repository root's
    args, _, controllers = parse_args(["fig5.1", "--policy", str(student), "--out", str(tmp_path / "o")])
    assert args.teacher == want and [c.label for c in controllers] == ["student", "teacher"]
    with pytest.raises(ValueError, match="names no teacher"):
        distilled_from(STUDENT)
    with pytest.raises(SystemExit):   # argparse's error: the untrained placeholder was not distilled
        parse_args(["fig5.1", "--policy", str(STUDENT)])


def test_push_and_wall_trials_differ_by_seed_within_their_spreads():
    """Lockstep trials are deterministic: without a seeded difference 20 trials would be one trial 20 times."""
    import math

    from sim_hil.faults import parse_faults
    pushes = plans.push_specs(30, plans.PUSH_SECONDS, 0)
    assert pushes == plans.push_specs(30, plans.PUSH_SECONDS, 0)          # same seed, same trial
    assert len({p.faults for p in pushes}) == len(pushes)
    for spec in pushes:
        (push,) = parse_faults(spec.faults)
        x, y = push.params["x"], push.params["y"]
        assert abs(math.hypot(x, y) / plans.PUSH_IMPULSE_NS - 1.0) <= plans.PUSH_IMPULSE_SPREAD + 1e-3
        assert (x > 0) == (spec.tag == "forward") and abs(math.atan2(y, abs(x))) <= plans.PUSH_ANGLE_SPREAD_RAD + 1e-3
        assert plans.PUSH_AT_S <= push.start_s <= plans.PUSH_AT_S + plans.PUSH_TIME_SPREAD_S
    starts = [w.command_start_s for w in plans.wall_specs(5, plans.WALL_SECONDS, 0)]
    assert len(set(starts)) == 5
    assert all(plans.STANDING_PREPARE_S <= s <= plans.STANDING_PREPARE_S + plans.WALL_START_SPREAD_S for s in starts)


def test_course_operator_steers_back_down_the_course_only_while_upright():
    """Walls and puddles: the robot may rise from a fall facing anywhere; the operator turns it back to +x."""
    import math

    from common.events import heading_from_quat
    from sim_hil.eval.trial import STEER_MAX_RPS, STEER_MIN_UP_Z, operator_yaw_rate
    assert operator_yaw_rate(0.0, 0.0, 1.0) == 0.0
    assert 0.0 < operator_yaw_rate(0.0, -0.1, 1.0) < STEER_MAX_RPS       # facing right of the course: turn left
    assert operator_yaw_rate(0.0, 0.1, 1.0) == -operator_yaw_rate(0.0, -0.1, 1.0)
    assert operator_yaw_rate(0.0, -2.0, 1.0) == STEER_MAX_RPS             # capped
    assert operator_yaw_rate(0.0, 3.0, 1.0) == -STEER_MAX_RPS and operator_yaw_rate(0.0, -3.0, 1.0) == STEER_MAX_RPS
    assert operator_yaw_rate(3.0, -3.0, 1.0) < 0.0                         # the short way round through ±π
    assert operator_yaw_rate(0.0, 1.0, STEER_MIN_UP_Z - 0.01) == 0.0      # lying down: no heading to steer
    half = 0.7
    assert math.isclose(heading_from_quat((math.cos(half / 2), 0.0, 0.0, math.sin(half / 2))), half)
    for specs in (plans.wall_specs(2, plans.WALL_SECONDS, 0), plans.puddle_specs(2, plans.PUDDLE_SECONDS, 0)):
        assert all(s.steer_heading_rad == plans.COURSE_HEADING_RAD for s in specs)
