"""The rise planner (training/planner/): MPPI on the training physics, its demonstrations and its CLI, on tiny
cases (a few samples, tenths of a second of motion)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from common import observation as obsdef
from common.events import LYING_SIDES
from training.envs import sagittal
from training.planner import __main__ as cli
from training.planner import batch, demos
from training.planner.mppi import Planner

TINY = ["samples=4", "horizon_s=0.2", "max_seconds=0.2", "hold_s=0.1"]


@pytest.fixture(scope="module")
def tiny():
    return batch.build(TINY)


def _start(env, seed):
    return (a[0].astype(np.float64) for a in env.fallen_starts(1, seed))


def test_a_plan_is_reproducible_from_its_seed_and_recorded_consistently(tiny):
    cfg, env, planner = tiny
    qpos, qvel = _start(env, 62)
    a, b = (planner.rise(qpos, qvel, planner.default_pose, 7) for _ in range(2))
    c = planner.rise(qpos, qvel, planner.default_pose, 8)
    steps = int(round(cfg.max_seconds / planner.ctrl_dt))
    assert a.targets.shape == (steps, 23) and a.qpos.shape == (steps + 1, env.mj_model.nq)
    assert np.array_equal(a.qpos, b.qpos) and np.array_equal(a.targets, b.targets)     # same machine, same seed
    assert not np.array_equal(a.targets, c.targets)
    np.testing.assert_allclose(a.qpos[0], qpos)
    # the observation is the getup actor's, of each recorded state
    assert a.obs.shape == (steps + 1, obsdef.observation_size(obsdef.TERMS_GETUP))
    np.testing.assert_allclose(a.obs[:, -23:], a.qvel[:, 6:], atol=1e-5)        # joint_vel, the last term
    assert np.all(a.targets >= planner.lo - 1e-12) and np.all(a.targets <= planner.hi + 1e-12)
    assert a.energy_J > 0 and a.cpu_s > 0 and a.gate_time_s is None                # 0.2 s: still on the floor


def test_the_robot_runs_the_training_physics(tiny):
    """Replaying a demonstration's targets through the env's CPU physics from its start gives its states."""
    cfg, env, planner = tiny
    qpos, qvel = _start(env, 3)
    demo = planner.rise(qpos, qvel, planner.default_pose, 0)
    physics = env.cpu_physics
    b = physics.evaluation_batch(1)
    b.qpos[:], b.qvel[:], b.time[:], b.qacc_warmstart[:] = qpos, qvel, 0.0, 0.0
    physics.write_targets(b, planner.default_pose[None], planner.default_pose[None])
    b.forward()
    for t, q_des in enumerate(demo.targets):
        physics.write_targets(b, q_des[None])
        b.step(nstep=physics.n_substeps)
        np.testing.assert_allclose(b.qpos[0], demo.qpos[t + 1], atol=1e-6)


@pytest.mark.slow
def test_from_the_kneel_the_planner_keeps_the_robot_kneeling_upright():
    """With the config's balance exploration, 1 s from the kneel keyframe: the trunk stays at kneeling height
    and within 10° of vertical, and the gate (0.57°) holds in a share of the steps: the sampler balances."""
    from common import model as t1model
    cfg, env, planner = batch.build(["samples=16", "max_seconds=1.0", "hold_s=1.0"])
    kneel = t1model.keyframe_qpos(env.mj_model, "kneel")
    demo = planner.rise(kneel, np.zeros(env.mj_model.nv), kneel[7:30], 0)
    assert np.all(np.abs(demo.trunk_height - planner.target["h"]) < 0.05)
    assert demo.up_z.min() > np.cos(np.radians(10.0)) and demo.gate.mean() > 0.2


def test_the_cli_writes_demos_and_a_report_split_by_side_and_goes_on(tiny, tmp_path, capsys):
    out = tmp_path / "demos"
    args = ["--seeds", "62,3", "--out", str(out), *sum((["--config", c] for c in TINY), [])]
    assert cli.main([*args, "--jobs", "2"]) == 0
    _, env, planner = tiny          # a worker's plan is the one planned in this process
    same = planner.rise(*_start(env, 3), planner.default_pose, 3)
    np.testing.assert_array_equal(demos.load(out / "demo_3.npz").targets, same.targets.astype(np.float32))
    report = json.loads((out / demos.REPORT).read_text())
    assert [r["seed"] for r in report["demos"]] == [3, 62]
    assert report["summary"]["all"]["demos"] == 2 and report["summary"]["all"]["met_gate"] == 0
    assert {r["side"] for r in report["demos"]} <= set(LYING_SIDES)
    assert all((out / f"strip_{r['side']}.png").exists() for r in report["demos"] if r["side"] != "side")
    before = (out / "demo_62.npz").stat().st_mtime_ns
    assert cli.main([*args[:1], "62", *args[2:]]) == 0                    # kept, not planned again
    assert (out / "demo_62.npz").stat().st_mtime_ns == before
    assert cli.main([*args, "--config", "samples=5"]) == 2
    assert "planned with another config" in capsys.readouterr().err


def test_bad_input_is_refused_naming_the_problem(tmp_path, capsys):
    assert cli.main(["--seeds", "x", "--out", str(tmp_path)]) == 2
    assert "--seeds 'x'" in capsys.readouterr().err
    assert cli.main(["--seeds", "0", "--out", str(tmp_path), "--jobs", "0"]) == 2
    assert "--jobs" in capsys.readouterr().err
    assert cli.main(["--seeds", "0", "--out", str(tmp_path), "--config", "no_such=1"]) == 2
    assert "no_such" in capsys.readouterr().err
    bad = tmp_path / "demo_1.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a planner demonstration"):
        demos.load(bad)


def test_a_knot_spacing_that_does_not_divide_is_refused(tiny):
    cfg, env, _ = tiny
    bad = cfg.copy_and_resolve_references()
    bad.knot_dt_s = 0.03
    with pytest.raises(ValueError, match="knot_dt_s / the control step"):
        Planner(env.cpu_physics, bad, np.zeros(23), 0.5)


def test_sagittal_plans_move_pitch_pairs_together_and_hold_the_rest_home(tiny):
    """sagittal_from: from that waypoint on, the robot's targets are in the getup env's sagittal action space."""
    cfg, env, planner = tiny
    mirrored = cfg.copy_and_resolve_references()
    mirrored.sagittal_from = cfg.waypoints[0]
    p = Planner(env.cpu_physics, mirrored, planner.default_pose, planner.action_scale)
    qpos, qvel = _start(env, 62)
    demo = p.rise(qpos, qvel, p.default_pose, 7)
    e = sagittal.expansion()
    pitch = (demo.targets - p.default_pose) @ e / e.sum(axis=0)
    np.testing.assert_allclose(demo.targets, p.default_pose + pitch @ e.T, atol=1e-9)
    assert np.ptp(pitch, axis=0).max() > 0.01                            # and they do move
    mirrored.sagittal_from = "crawl"
    with pytest.raises(ValueError, match="sagittal_from 'crawl' is not a waypoint"):
        Planner(env.cpu_physics, mirrored, planner.default_pose, planner.action_scale)


def test_summary_counts_gate_met_within_the_time_per_side():
    rows = [{"side": "face_down", "gate_time_s": 2.0, "held_share": 0.9, "cpu_s": 10, "energy_J": 100},
            {"side": "face_down", "gate_time_s": None, "held_share": 0.0, "cpu_s": 30, "energy_J": 300},
            {"side": "on_back", "gate_time_s": 7.0, "held_share": 1.0, "cpu_s": 20, "energy_J": 200}]
    s = demos.summarise(rows, within_s=6.0)
    assert s["face_down"]["share"] == 0.5 and s["on_back"]["share"] == 0.0 and s["all"]["met_gate"] == 1
    assert s["on_back"]["met_gate_by_end"] == 1 and s["all"]["met_gate_by_end"] == 2
    assert "side" not in s and s["all"]["reached_kneeling_height"] == 0 and s["all"]["best_tilt_deg"] is None


def test_a_killed_batch_leaves_no_worker_planning_on():
    """--jobs workers get SIGTERM when the batch dies (PR_SET_PDEATHSIG), instead of planning on as orphans."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path
    script = ("import multiprocessing as mp, time\nfrom concurrent.futures import ProcessPoolExecutor\n"
              "from training.planner import batch\n"
              "pool = ProcessPoolExecutor(1, mp_context=mp.get_context('spawn'), initializer=batch.end_with_parent)\n"
              "pool.submit(time.sleep, 0.1).result()\npool.submit(time.sleep, 600)\n"
              "print(*pool._processes, flush=True)\ntime.sleep(600)\n")
    root = Path(__file__).resolve().parents[1]
    batch_proc = subprocess.Popen([sys.executable, "-c", script], cwd=root, stdout=subprocess.PIPE, text=True,
                                  env={**os.environ, "PYTHONPATH": os.pathsep.join([str(root), *sys.path])})
    try:
        worker = int(batch_proc.stdout.readline())
        batch_proc.send_signal(signal.SIGKILL)
        batch_proc.wait(timeout=30)
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline and Path(f"/proc/{worker}").exists() and \
                Path(f"/proc/{worker}/stat").read_text().split()[2] != "Z":
            time.sleep(0.1)
        assert not Path(f"/proc/{worker}").exists() or Path(f"/proc/{worker}/stat").read_text().split()[2] == "Z"
    finally:
        batch_proc.kill()
