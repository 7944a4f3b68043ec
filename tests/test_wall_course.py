"""The low-wall course in the training worlds (training/envs/wall_course.py): the evaluation's walls moved
down +x, approaches to them, the landings of a joystick expert that walked into one (wall_approach.wall_bank),
and the unified env and the evaluation that start there. The slow tests roll the shipped joystick expert on
the CPU physics."""
from __future__ import annotations

import jax
import mujoco
import numpy as np
import pytest

from common import scenarios
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training import envs
from training.envs import wall_course
from training.envs.starts import wall_approach

JOYSTICK = "policies/joystick/joystick.safetensors"
APPROACHES = 8
SEED = 400_000


def _wall_xs(mj: mujoco.MjModel) -> list[float]:
    return sorted(float(mj.geom(f"wall_{i}").pos[0]) for i in range(scenarios.WALL_COUNT))


def test_training_course_is_the_evaluations_moved_down_x():
    spec = scenarios.robot_spec()
    wall_course.add_to_spec(spec, wall_course.config())
    train = spec.compile()
    evaluation = scenarios.robot_spec()
    scenarios.add_low_walls(evaluation)
    ev = evaluation.compile()
    shift = wall_course.FIRST_WALL_X_M - scenarios.WALL_FIRST_X_M
    np.testing.assert_allclose(_wall_xs(train), np.array(_wall_xs(ev)) + shift)
    for i in range(scenarios.WALL_COUNT):
        np.testing.assert_allclose(train.geom(f"wall_{i}").size, ev.geom(f"wall_{i}").size)


def test_approaches_start_before_the_first_wall_facing_it_with_a_forward_command():
    cfg = wall_course.config()
    xy, yaw, cmd = jax.vmap(lambda k: wall_course.course_start(k, cfg))(jax.random.split(jax.random.PRNGKey(0), 500))
    before = cfg.first_wall_x_m - np.asarray(xy[:, 0])
    assert before.min() >= wall_course.APPROACH_M[0] and before.max() <= wall_course.APPROACH_M[1]
    assert np.abs(np.asarray(xy[:, 1])).max() <= wall_course.APPROACH_LATERAL_M
    assert np.abs(np.asarray(yaw)).max() <= wall_course.APPROACH_YAW_RAD
    cmd = np.asarray(cmd)
    assert np.all((cmd[:, 0] >= wall_course.APPROACH_SPEED_MPS[0]) & (cmd[:, 0] <= wall_course.APPROACH_SPEED_MPS[1]))
    assert np.all(cmd[:, 1:] == 0.0)
    cfg.approach_m = [1.0, 5.0]                               # a longer run-up (config)
    xy, _, _ = jax.vmap(lambda k: wall_course.course_start(k, cfg))(jax.random.split(jax.random.PRNGKey(0), 500))
    before = cfg.first_wall_x_m - np.asarray(xy[:, 0])
    assert before.min() >= 1.0 and before.max() <= 5.0 and before.max() > wall_course.APPROACH_M[1]
    cfg.approach_m = [2.0, 1.0]
    with pytest.raises(ValueError, match="approach_m"):
        wall_course.course_start(jax.random.PRNGKey(0), cfg)


def test_course_progress_is_banked_and_paid_at_no_more_than_the_command():
    dt, cap = 0.02, 0.4
    best, credit, gained = wall_course.credited_progress(30.0, 30.0, 30.0, cap, dt)     # standing still
    assert float(gained) == 0.0
    best, credit, gained = wall_course.credited_progress(best, credit, 30.02, cap, dt)   # sprinting: capped
    assert float(gained) == pytest.approx(cap * dt, abs=1e-5)
    best, credit, gained = wall_course.credited_progress(best, credit, 30.8, cap, dt)    # a fall across the wall
    paid = [float(gained)]
    for _ in range(200):                                                                # getting up in place
        best, credit, gained = wall_course.credited_progress(best, credit, 30.6, cap, dt)
        paid.append(float(gained))
    assert max(paid) == pytest.approx(cap * dt, abs=1e-5) and paid[-1] == 0.0
    assert float(credit) == pytest.approx(30.8, abs=1e-5) and sum(paid) == pytest.approx(0.8 - cap * dt, abs=1e-4)
    for x in (30.5, 30.8, 30.5, 30.8):                                                  # back and forth: nothing new
        best, credit, gained = wall_course.credited_progress(best, credit, x, cap, dt)
        assert float(gained) == 0.0
    assert float(wall_course.credited_progress(30.0, 30.0, 31.0, -0.2, dt)[2]) == 0.0  # a backward command


def test_envs_have_the_course_only_when_asked():
    plain = envs.make("getup", config_overrides={"backend": "cpu", "fallen.bank_starts": 2})
    assert not plain.has_wall_course() and plain.mj_model.ngeom == envs.make(
        "getup", config_overrides={"fallen.bank_starts": 2}).mj_model.ngeom
    walled = envs.make("unified", config_overrides={"backend": "cpu", "fallen.bank_starts": 2, "walls.prob": 0.5})
    assert walled.has_wall_course()
    assert _wall_xs(walled.mj_model)[0] == pytest.approx(wall_course.FIRST_WALL_X_M)


@pytest.mark.parametrize("task, over, why", [
    ("getup", {"wall_course.enable": True}, "needs backend 'cpu'"),
    ("unified", {"backend": "cpu", "walls.prob": 1.5}, r"walls.prob must be in \[0, 1\]")])
def test_bad_wall_configs_are_refused(task, over, why):
    with pytest.raises(ValueError, match=why):
        envs.make(task, config_overrides={"fallen.bank_starts": 2, **over})


@pytest.fixture(scope="module")
def wall_bank():
    return wall_approach.wall_bank(envs.make, JOYSTICK, APPROACHES, SEED)


@pytest.mark.slow
def test_wall_bank_holds_falls_at_the_first_wall(wall_bank):
    qpos, qvel = wall_bank
    assert 1 <= qpos.shape[0] <= APPROACHES and np.all(np.isfinite(qvel))
    env = envs.make("joystick", config_overrides={"backend": "cpu", "wall_course.enable": True})
    mj, data = env.mj_model, mujoco.MjData(env.mj_model)
    waist = mj.body("Waist").id
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_kinematics(mj, data)
        assert WAIST_SWITCH_HEIGHT_M - 0.1 < data.xpos[waist, 2] < WAIST_SWITCH_HEIGHT_M   # the first tick below
    # the trunk is over or just before the wall it walked into (the walls are 0.1 m thick)
    near = np.abs(qpos[:, 0] - wall_course.FIRST_WALL_X_M) < 1.0
    assert near.mean() >= 0.5


@pytest.mark.slow
def test_unified_wall_episodes_walk_at_the_course_and_hold_their_command():
    env = envs.make("unified", config_overrides={"backend": "cpu", "fallen.bank_starts": 2, "walls.prob": 1.0,
                                                 "command_resample_steps": 1, "noise.level": 0.0})
    state = jax.jit(env.reset)(jax.random.PRNGKey(5))
    x = float(state.data.qpos[0])
    before = wall_course.FIRST_WALL_X_M - x
    assert wall_course.APPROACH_M[0] <= before <= wall_course.APPROACH_M[1]
    assert bool(state.info["course"]) and int(state.info["start_kind"]) == 2   # counted with the standing ones
    command = np.asarray(state.info["command"])
    state = jax.jit(env.step)(state, np.zeros(env.action_size, np.float32))   # a resample is due every tick
    np.testing.assert_array_equal(np.asarray(state.info["command"]), command)


@pytest.mark.slow
def test_evaluate_from_wall_landings(wall_bank, tmp_path):
    from training.evaluation.batch import evaluate
    report = evaluate("policies/getup_knockdown/getup_knockdown.safetensors", tmp_path, seeds=APPROACHES, seconds=0.2,
                      first_seed=SEED, backend="cpu", starts="wall", start_joystick=JOYSTICK).read_text()
    assert f"{wall_bank[0].shape[0]} landings at a low wall (of {APPROACHES} approaches" in report
    assert "seed: policy" not in report
