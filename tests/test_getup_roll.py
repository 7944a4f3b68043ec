"""The roll task (training/envs/getup_roll.py): on the back or side → face down, the keyframe getup's stage 0."""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from common import events
from training import envs
from training.envs import getup_rewards as G

SMALL = {"episode_length": 20, "fallen.bank_starts": 12, "fallen.side_weights": [0, 1, 1]}


def test_turn_reward_runs_from_the_back_to_face_down():
    np.testing.assert_allclose(np.asarray(G.turn_reward(jnp.array([1.0, 0.0, -1.0]))), [0.0, 0.5, 1.0])


def test_the_recipe_starts_the_roll_on_the_back_or_side_only():
    from training.recipes import base as R
    assert R.load("getup_keyframe").stage("roll").config["env.fallen.side_weights"] == [0, 1, 1]
    cfg = envs.default_config("getup_roll")
    assert list(cfg.start_probs) == [1.0, 0.0, 0.0]
    assert set(cfg.reward.scales) == {"turn", "rolled", "pose", "energy"} and cfg.reward.scales.energy == 0.0


@pytest.fixture(scope="module")
def env():
    return envs.make("getup_roll", config_overrides=SMALL)


def test_no_start_lies_face_down_and_the_info_reads_the_trunk(env):
    forward_z = events.forward_z_from_quat(np.asarray(env._fallen_qpos)[:, 3:7])
    assert len(forward_z) > 0 and np.all(forward_z >= -events.FACING_Z)
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    assert float(state.info["forward_z"]) == pytest.approx(
        float(events.forward_z_from_quat(np.asarray(state.data.qpos[3:7]))), abs=1e-4)
    assert not bool(state.info["rolled"])


def test_a_robot_lying_still_face_down_in_the_default_pose_earns_every_term(env):
    qpos = np.asarray(env._home_qpos).copy()
    qpos[2], qpos[3:7] = 0.12, [np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0]     # pitched 90°: face down
    data = env.make_data(jnp.asarray(qpos), jnp.zeros(env.mj_model.nv))
    info = {**env.body_readings(data)}
    info.update(env._task_info(info, data))
    terms = env._reward_terms(data, info)
    assert bool(info["rolled"]) and float(info["forward_z"]) == pytest.approx(-1.0, abs=1e-4)
    assert float(terms["turn"]) == pytest.approx(1.0, abs=1e-4) and float(terms["rolled"]) == 1.0
    assert float(terms["pose"]) == pytest.approx(1.0, abs=1e-4)
    assert bool(env._success(info))
