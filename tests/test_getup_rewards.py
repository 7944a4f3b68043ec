"""Getup reward terms against hand computations on fixed states (training/envs/getup_rewards.py and the
getup env's reward_terms / stage switch). No env jit here: fast."""
from __future__ import annotations

import math
from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np
import pytest

from training import envs
from training.envs import getup_rewards as G

HOME_H = 0.66585   # sim_hil/models/t1.xml keyframe home, trunk z [m]
KNEEL_H = 0.40535  # keyframe kneel, trunk z [m]


def test_height_and_orientation_formula():
    for h, target in [(0.1, KNEEL_H), (0.4, KNEEL_H), (0.7, HOME_H), (HOME_H, HOME_H)]:
        assert float(G.height_reward(h, target)) == pytest.approx(math.exp(-abs(h - target) / 0.1), rel=1e-6)
    for up_z in (-1.0, 0.0, 0.5, 1.0):
        assert float(G.orientation_reward(up_z)) == pytest.approx((1 + up_z) / 2, abs=1e-7)


def test_pose_reward():
    q_ref = np.linspace(-1, 1, 23)
    q = q_ref + 0.1 * np.arange(23) / 23
    expected = math.exp(-0.5 * float(np.sum((q - q_ref) ** 2)))
    assert float(G.pose_reward(jnp.asarray(q), jnp.asarray(q_ref))) == pytest.approx(expected, rel=1e-5)
    assert float(G.pose_reward(jnp.asarray(q_ref), jnp.asarray(q_ref))) == pytest.approx(1.0)


def test_energy_cost():
    dq = np.array([1.0, -2.0, 0.5] + [0.0] * 20)
    tau = np.array([3.0, 4.0, -10.0] + [1.0] * 20)
    tau_max = np.array([7.0, 7.0, 18.0] + [30.0] * 20)
    expected = 3.0 / 7.0 + 8.0 / 7.0 + 5.0 / 18.0
    assert float(G.energy_cost(jnp.asarray(dq), jnp.asarray(tau), jnp.asarray(tau_max))) == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("h, target, ok", [
    (0.405, 0.405, True), (0.4099, 0.405, True), (0.4101, 0.405, False),   # within / beyond 5 mm
    (0.399, 0.398, False),                                                  # below the 0.4 m floor
    (HOME_H + 0.004, HOME_H, True), (HOME_H - 0.006, HOME_H, False)])
def test_gate_height(h, target, ok):
    assert bool(G.gate_height(h, target)) is ok


@pytest.mark.parametrize("up_z, ok", [(1.0, True), (0.9901, True), (0.9899, False), (-1.0, False)])
def test_gate_upright(up_z, ok):
    assert bool(G.gate_upright(up_z)) is ok
    assert bool(G.gate(HOME_H, HOME_H, up_z)) is ok
    assert not bool(G.gate(0.3, HOME_H, up_z))  # both conditions are needed


def test_bonuses():
    assert float(G.height_bonus(jnp.asarray(True))) == pytest.approx(1.83)
    assert float(G.height_bonus(jnp.asarray(False))) == 0.0
    assert float(G.pose_bonus(jnp.asarray(True), 0.5)) == pytest.approx(0.3)
    assert float(G.pose_bonus(jnp.asarray(False), 0.5)) == 0.0


def test_stage_switch_function():
    kneel, home = 1.0, 2.0
    # stage 1: always kneel
    assert float(G.select_target(jnp.asarray(True), jnp.asarray(True), kneel, home)) == kneel
    # full task: kneel until the kneel gate has been passed, then home
    assert float(G.select_target(jnp.asarray(False), jnp.asarray(False), kneel, home)) == kneel
    assert float(G.select_target(jnp.asarray(True), jnp.asarray(False), kneel, home)) == home


@pytest.fixture(scope="module")
def full_env():
    return envs.make("getup", config_overrides={"fallen_bank_size": 2, "episode_length": 20})


def _fake_data(qpos, qvel, tau):
    return SimpleNamespace(qpos=jnp.asarray(qpos), qvel=jnp.asarray(qvel), actuator_force=jnp.asarray(tau))


def test_env_targets_and_stage_switch(full_env):
    h, q, home = full_env.targets(jnp.asarray(False))
    assert float(h) == pytest.approx(KNEEL_H, abs=1e-6) and not bool(home)
    np.testing.assert_allclose(np.asarray(q), np.asarray(full_env._kneel_qpos[7:]), atol=1e-7)
    h, q, home = full_env.targets(jnp.asarray(True))
    assert float(h) == pytest.approx(HOME_H, abs=1e-6) and bool(home)
    np.testing.assert_allclose(np.asarray(q), np.asarray(full_env._default_pose), atol=1e-7)
    s1 = envs.make("getup", config_overrides={"stage": "stage1", "fallen_bank_size": 2})
    assert float(s1.targets(jnp.asarray(True))[0]) == pytest.approx(KNEEL_H, abs=1e-6)


def test_env_reward_terms_by_hand(full_env):
    """A kneeling state at the kneel target: gate on, all terms by hand."""
    qpos = np.asarray(full_env._kneel_qpos).copy()
    qpos[7:] += 0.05
    qvel = np.zeros(29)
    qvel[6:] = 0.3
    tau = np.full(23, 2.0)
    info = {"reached_kneel": jnp.asarray(False), "trunk_height": jnp.asarray(KNEEL_H + 0.002),
            "up_z": jnp.asarray(0.995)}
    terms = full_env.reward_terms(_fake_data(qpos, qvel, tau), info)
    pose = math.exp(-0.5 * 23 * 0.05 ** 2)
    limits = np.asarray(full_env._tau_limit)
    assert bool(terms["gate"])
    assert float(terms["height"]) == pytest.approx(math.exp(-0.002 / 0.1), rel=1e-4)
    assert float(terms["orientation"]) == pytest.approx(0.9975, rel=1e-6)
    assert float(terms["pose"]) == pytest.approx(pose, rel=1e-5)
    assert float(terms["height_bonus"]) == pytest.approx(1.83)
    assert float(terms["pose_bonus"]) == pytest.approx(0.6 * pose, rel=1e-5)
    assert float(terms["energy"]) == pytest.approx(float(np.sum(0.3 * 2.0 / limits)), rel=1e-5)
    # same state once the kneel stage is done: the target is home, so the gate is off
    info["reached_kneel"] = jnp.asarray(True)
    terms = full_env.reward_terms(_fake_data(qpos, qvel, tau), info)
    assert not bool(terms["gate"]) and float(terms["height_bonus"]) == 0.0


def test_start_probabilities_per_stage(full_env):
    assert full_env.start_probabilities() == pytest.approx([0.4, 0.4, 0.2])
    s2 = envs.make("getup", config_overrides={"stage": "stage2"})
    assert s2.start_probabilities() == [0.0, 1.0, 0.0]
    with pytest.raises(ValueError, match="stage"):
        envs.make("getup", config_overrides={"stage": "stage3", "fallen_bank_size": 2})
    with pytest.raises(ValueError, match="start_probs"):
        envs.make("getup", config_overrides={"start_probs": [0.5, 0.5, 0.5], "fallen_bank_size": 2})
