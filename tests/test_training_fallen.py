"""The getup tasks' fallen starts are the loop's: the settled fall after the runtime's PREPARE ramp
(training/envs/starts/fallen.py; its gains and ramp are the contract's, as the runtime's). The ramp's effect,
and the state at the first POLICY tick of a real lockstep run (t1-runtime + sim_hil) against the precomputed one."""
from __future__ import annotations

import numpy as np
import pytest

from common import model as t1model
from sim_hil import config as sim_config
from sim_hil.launch import ROOT
from training.envs import base
from training.envs.starts import fallen

UNTRAINED_STUDENT = ROOT / "policies" / "student_untrained" / "student_untrained.safetensors"
SUPERVISOR = (base.base_config().supervisor.max_target_speed_rps, base.base_config().supervisor.joint_range_fraction)
SEEDS = 4
MODE_POLICY = 3                      # runtime/include/t1rt/safety.hpp Mode::kPolicy
LOOP_JOINT_TOL_RAD = 0.15            # bus latency and the two PASSIVE / DAMPING ticks are not modelled
LOOP_ROOT_TOL_M = 0.03


def test_prepare_straightens_the_lying_robot_without_standing_it_up():
    raw_q, _ = fallen.fallen_states(SEEDS, 0)
    q, v = fallen.fallen_states(SEEDS, 0, fallen.PREPARE_S, SUPERVISOR)
    home = t1model.default_pose(t1model.load_model())
    legs = slice(t1model.ROOT_QPOS + 11, t1model.ROOT_QPOS + 23)
    err_raw = np.abs(raw_q[:, legs] - home[11:]).mean()
    err = np.abs(q[:, legs] - home[11:]).mean()
    assert err < 0.25 * err_raw, (err, err_raw)   # the stiff leg gains reach the default pose
    assert np.all(q[:, 2] < 0.3)                  # still lying: PREPARE is no getup
    assert np.all(np.isfinite(v))
    again, _ = fallen.fallen_states(SEEDS, 0, fallen.PREPARE_S, SUPERVISOR)
    np.testing.assert_array_equal(again, q)      # cached and deterministic
    again[0, 2] = 9.0                            # a copy: the cache stays intact
    assert fallen.fallen_states(SEEDS, 0, fallen.PREPARE_S, SUPERVISOR)[0][0, 2] != 9.0


def test_bad_arguments_name_the_problem():
    with pytest.raises(ValueError, match="prepare_s"):
        fallen.fallen_states(2, 0, -1.0, SUPERVISOR)
    with pytest.raises(ValueError, match="supervisor"):
        fallen.fallen_states(2, 0, 2.0)
    with pytest.raises(ValueError, match="seed"):
        fallen.fallen_states(2, -3)


def test_the_bank_draws_each_side_in_proportion_to_its_weight():
    from common.events import LYING_SIDES, lying_side
    qpos, qvel = fallen.fallen_states(16, 0)
    sides = np.array([lying_side(float(z)) for z in t1model.trunk_forward_z(qpos)])
    same = fallen.weight_sides(qpos, qvel, [1, 1, 1])
    np.testing.assert_array_equal(same[0], qpos)
    more, vel = fallen.weight_sides(qpos, qvel, [1, 3, 2])
    counts = {s: int((sides == s).sum()) for s in LYING_SIDES}
    assert len(more) == len(vel) == counts["face_down"] + 3 * counts["on_back"] + 2 * counts["side"]
    assert counts["on_back"] > 0 and all(any((r == q).all() for r in more) for q in qpos)   # none left out
    no_face_down, _ = fallen.weight_sides(qpos, qvel, [0, 1, 1])    # the roll's starts: the face-down ones left out
    assert len(no_face_down) == counts["on_back"] + counts["side"]
    assert all(lying_side(float(z)) != "face_down" for z in t1model.trunk_forward_z(no_face_down))
    for bad in ([0, 0, 0], [1, -1, 1], [1, 1.5, 1], [1, 1], [True, 1, 1]):
        with pytest.raises(ValueError, match="side_weights"):
            fallen.weight_sides(qpos, qvel, bad)


def test_the_first_policy_tick_of_the_loop_starts_where_training_does(netns):
    from sim_hil.launch import start_runtime, stop, wait_until_listening
    from sim_hil.sim import SimConfig, Simulator

    expected_q, _ = fallen.fallen_states(2, 0, fallen.PREPARE_S, SUPERVISOR)
    for seed in range(2):
        sim = Simulator(SimConfig(scenario="flat", spawn=f"fallen:{seed}", clock="lockstep", seed=seed,
                                  lcm_url=netns, status_rate_hz=1.0 / sim_config.LOOP_PERIOD_S))
        runtime = start_runtime(UNTRAINED_STUDENT, "--clock", "lockstep", "--autostart",
                                "--prepare-s", f"{fallen.PREPARE_S:g}", "--lcm-url", netns)
        wait_until_listening(runtime)
        at_policy = None
        try:
            for _ in range(int(2 * fallen.PREPARE_S / sim_config.LOOP_PERIOD_S)):
                sim.tick()
                if sim.link.latest is not None and sim.link.latest.mode == MODE_POLICY:
                    at_policy = sim.data.qpos.copy()
                    break
        finally:
            sim.close()
            stop(runtime)
        assert at_policy is not None, "the runtime never reached POLICY"
        joints = slice(t1model.ROOT_QPOS, None)
        assert np.abs(at_policy[joints] - expected_q[seed, joints]).max() < LOOP_JOINT_TOL_RAD
        assert np.linalg.norm(at_policy[:3] - expected_q[seed, :3]) < LOOP_ROOT_TOL_M
