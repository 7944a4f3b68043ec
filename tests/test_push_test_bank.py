"""The loop's push test in the batch (training/envs/starts/push.py push_test_bank, torso_impulse_dqvel): the same
draws as sim_hil's trials, the same torso impulse, and `evaluate --starts push` starts from its landings. The
slow tests roll the shipped joystick expert (CPU physics)."""
from __future__ import annotations

import math

import jax
import mujoco
import numpy as np
import pytest

from common import model as t1model
from messages.contract import WAIST_SWITCH_HEIGHT_M
from sim_hil.eval import plans
from sim_hil.faults import parse_faults
from training import envs
from training.envs.starts import push

JOYSTICK = "policies/joystick/joystick.safetensors"
STARTS = 6
SEED = 500_000   # the bank's first seed (the card's screen uses 510 000)


def test_push_specs_are_the_draws_the_bank_uses():
    for i, spec in enumerate(plans.push_specs(6, plans.PUSH_SECONDS, 40)):
        draw = plans.push_draw(i, 40 + i)
        (push,) = parse_faults(spec.faults)
        assert (spec.tag == "forward") == draw.forward
        assert push.params["x"] == pytest.approx(draw.impulse_ns * math.cos(draw.angle_rad), abs=0.01)
        assert push.params["y"] == pytest.approx(draw.impulse_ns * math.sin(draw.angle_rad), abs=0.01)
        assert push.start_s == pytest.approx(draw.at_s, abs=1e-3)


def test_torso_impulse_is_what_sim_hil_does_in_one_physics_step():
    """In the air and without gravity, sim_hil's push (impulse / dt on the Trunk for one step) changes qvel by
    M⁻¹ Jᵀ impulse, and the robot's momentum by the impulse."""
    model = t1model.load_model()
    model.opt.gravity[:] = 0.0
    data = mujoco.MjData(model)
    qpos = t1model.keyframe_qpos(model, "home")
    qpos[2] += 1.0                                         # in the air: no contacts
    data.qpos[:] = qpos
    impulse = np.array([30.0, -12.0, 0.0])
    dqvel = push.torso_impulse_dqvel(model, mujoco.MjData(model), qpos, impulse)

    data.qvel[:] = 0.0
    data.ctrl[:] = 0.0
    data.xfrc_applied[model.body("Trunk").id, :3] = impulse / model.opt.timestep
    mujoco.mj_step(model, data)
    assert np.allclose(data.qvel, dqvel, atol=0.02 * np.abs(dqvel).max())

    data.qpos[:], data.qvel[:] = qpos, dqvel
    mujoco.mj_forward(model, data)
    mujoco.mj_subtreeVel(model, data)
    mass = model.body_subtreemass[1]
    assert np.allclose(mass * data.subtree_linvel[1], impulse, atol=1e-6 * np.abs(impulse).max() + 1e-6)


@pytest.fixture(scope="module")
def push_bank():
    return push.push_test_bank(envs.make, JOYSTICK, STARTS, seed=SEED)


@pytest.mark.slow
def test_push_bank_holds_the_falls_of_the_push_test(push_bank):
    """The first tick below the switch, still falling, with the shove's momentum."""
    qpos, qvel = push_bank
    model = t1model.load_model()
    data = mujoco.MjData(model)
    assert 1 <= qpos.shape[0] <= STARTS
    for q in qpos:
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        assert WAIST_SWITCH_HEIGHT_M - 0.1 < data.xpos[model.body("Waist").id, 2] < WAIST_SWITCH_HEIGHT_M
    assert np.all(np.isfinite(qvel)) and np.median(qvel[:, 2]) < 0.0
    assert np.median(np.hypot(qvel[:, 0], qvel[:, 1])) > 0.3


@pytest.mark.slow
def test_evaluate_starts_from_push_landings(push_bank, tmp_path):
    from training.evaluation.batch import evaluate
    report = evaluate("policies/getup_knockdown/getup_knockdown.safetensors", tmp_path, seeds=STARTS, seconds=0.2,
                      first_seed=SEED, backend="cpu", starts="push", start_joystick=JOYSTICK).read_text()
    assert f"{push_bank[0].shape[0]} landings in the loop's push test (of {STARTS} standing starts" in report
    assert "| attempts per episode (the loop's push test counts per trial) |" in report


def test_unified_torso_shoves_are_the_push_tests_turned_to_the_heading():
    """knockdown.shove "torso": the knockdown share of the pushes is the test's shove, M⁻¹Jᵀ·impulse of the
    standing robot turned to its heading: the base moves along the shove (forward 2 : backward 1) and the
    robot's momentum is the test's impulse."""
    env = envs.make("unified", config_overrides={"knockdown.prob": 1.0, "knockdown.shove": "torso",
                                                 "fallen.bank_starts": 2})
    model = env.mj_model
    heading = 2.0
    qpos = np.asarray(t1model.keyframe_qpos(model, "home")).copy()
    qpos[3:7] = [math.cos(heading / 2), 0.0, 0.0, math.sin(heading / 2)]
    keys = jax.random.split(jax.random.PRNGKey(0), 600)
    dqvel = np.asarray(jax.vmap(env._torso_shove.dqvel, in_axes=(None, 0))(qpos, keys))
    along = dqvel[:, 0] * math.cos(heading) + dqvel[:, 1] * math.sin(heading)
    assert 0.6 < np.mean(along > 0) < 0.73                                 # forward 2 : backward 1
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mass = model.body_subtreemass[1]
    for dq in dqvel[:20]:
        data.qvel[:] = dq
        mujoco.mj_forward(model, data)
        mujoco.mj_subtreeVel(model, data)
        size = np.linalg.norm(mass * data.subtree_linvel[1])
        assert plans.PUSH_IMPULSE_NS * (1 - plans.PUSH_IMPULSE_SPREAD) - 1e-3 <= size
        assert size <= plans.PUSH_IMPULSE_NS * (1 + plans.PUSH_IMPULSE_SPREAD) + 1e-3
    with pytest.raises(ValueError, match="knockdown.shove 'elbow'"):
        envs.make("unified", config_overrides={"knockdown.shove": "elbow", "fallen.bank_starts": 2})


def test_unified_mixed_knockdowns_are_base_pushes_and_torso_shoves():
    """knockdown.shove "mixed": torso_share of the knockdowns are the push test's torso shove (_apply_push), the
    rest base-speed knockdowns (_push_magnitude)."""
    env = envs.make("unified", config_overrides={"knockdown.prob": 1.0, "knockdown.shove": "mixed",
                                                 "knockdown.torso_share": 0.25, "fallen.bank_starts": 2})
    assert env._torso_shove is not None
    walk_hi = envs.default_config("joystick").push.magnitude_range_mps[1]
    speeds = np.asarray(jax.vmap(env._push_magnitude)(jax.random.split(jax.random.PRNGKey(5), 4000)))
    assert 0.72 < np.mean(speeds > walk_hi) < 0.78           # 3000 ± 27 (1 σ) of 4000 draws
    with pytest.raises(ValueError, match="knockdown.torso_share must be in"):
        envs.make("unified", config_overrides={"knockdown.shove": "mixed", "knockdown.torso_share": 1.5,
                                               "fallen.bank_starts": 2})


@pytest.mark.slow
def test_unified_push_is_a_shove_only_when_due_and_drawn():
    env = envs.make("unified", config_overrides={"knockdown.prob": 1.0, "knockdown.shove": "torso",
                                                 "fallen.bank_starts": 2})
    qpos = jax.numpy.asarray(t1model.keyframe_qpos(env.mj_model, "home"))
    data = env.make_data(qpos, jax.numpy.zeros(env.mj_model.nv))
    keys = jax.random.split(jax.random.PRNGKey(1), 2)
    for step, pushed in ((8, True), (3, False)):           # due when push_step + 1 hits the interval
        info = {"push_step": jax.numpy.array(step), "push_interval_steps": jax.numpy.array(9)}
        after = env._apply_push(data, info, *keys)
        moved = np.abs(np.asarray(after.qvel)).max() > 0.1
        assert moved == pushed and int(info["push_step"]) == step + 1
        assert np.allclose(np.asarray(info["push"]), np.asarray(after.qvel)[:2])
