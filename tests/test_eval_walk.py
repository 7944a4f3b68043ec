"""The `walk` evaluation plan (the joystick expert's in-the-loop targets): its trials, the distance and
heading reductions of a trial, and one short end-to-end run with a lockstep and a realtime trial."""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from t1 import joint_command_t

from common import model as t1model
from sim_hil.eval import plans
from sim_hil.eval.metrics import TickLog
from sim_hil.eval.trial import TrialSpec, summarise
from sim_hil.launch import ROOT, _env

PLACEHOLDER = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"


def test_walk_runs_every_condition_per_trial_index():
    specs = plans.walk_specs(2, 5.0, 10)
    assert len(specs) == 2 * len(plans.WALK_CONDITIONS)
    by_tag = {s.tag: s for s in specs if s.seed == 10}
    assert by_tag["forward"].command_vx_mps == plans.WALK_FORWARD_MPS and by_tag["forward"].clock == "lockstep"
    assert by_tag["turn"].command_yaw_rps == plans.WALK_YAW_RPS and by_tag["turn"].command_vx_mps == 0.0
    assert by_tag["forward realtime"].clock == "realtime"
    assert by_tag["walk, turn, stop"].command_stop_s == plans.WALK_STOP_AT * 5.0
    assert by_tag["forward"].command_stop_s is None
    assert all(s.spawn == "standing" for s in specs)


def test_summarise_measures_distance_and_unwrapped_heading():
    n, start = 500, 50
    log = TickLog(t1model.load_model(), n)
    log.t[:] = np.arange(n) * 0.002
    log.trunk[:], log.up_z[:] = 0.66, 1.0
    log.mode[start:] = joint_command_t.MODE_POLICY
    heading = np.linspace(0.0, 3 * math.pi, n)            # one and a half turns: wraps twice
    log.yaw[:] = np.angle(np.exp(1j * heading))
    log.base_x[:], log.base_y[:] = np.linspace(1.0, 4.0, n), 2.0
    r = summarise(TrialSpec("flat", 0, "standing", 1.0, tag="turn"), "joystick", log, None)
    assert math.isclose(r.yaw_turned_rad, heading[-1] - heading[start], rel_tol=1e-6)
    assert math.isclose(r.drift_m, 4.0 - log.base_x[start], rel_tol=1e-9)
    stopped = summarise(TrialSpec("flat", 0, "standing", 1.0, command_stop_s=0.5, tag="walk, turn, stop"),
                        "joystick", log, None)
    assert math.isclose(stopped.after_stop_m, 4.0 - log.base_x[250], rel_tol=1e-9)   # t = 0.5 s at tick 250
    assert math.isnan(r.after_stop_m)


@pytest.mark.slow
def test_walk_plan_end_to_end_with_a_realtime_trial(tmp_path, netns):
    out = tmp_path / "walk"
    cmd = [sys.executable, "-m", "sim_hil.eval", "walk", "--policy", str(PLACEHOLDER), "--label", "joystick",
           "--trials", "1", "--seconds", "0.5", "--jobs", "1", "--no-video", "--out", str(out)]
    run = subprocess.run(cmd, cwd=ROOT, env=_env(), capture_output=True, text=True, timeout=150)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    results = json.loads((out / "results.json").read_text())
    assert sorted(t["spec"]["tag"] for t in results["trials"]) == sorted(c[0] for c in plans.WALK_CONDITIONS)
    assert {t["spec"]["clock"] for t in results["trials"]} == {"lockstep", "realtime"}
    report = (out / "report.md").read_text()
    assert "turn: heading turned [rad]" in report and "joystick: UNTRAINED" in report
    assert "walk, turn, stop: distance after the stop [m]" in report
    assert "seed (student)" not in report
