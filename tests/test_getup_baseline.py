"""The baseline getup task's options (training/envs/getup_baseline.py): the energy fine-tune and the
standing-start share, stepped on the CPU backend (compiles in seconds)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import pytest

from training import envs
from training.envs import getup_rewards as G

SMALL = {"backend": "cpu", "episode_length": 20, "fallen.bank_starts": 2}
ENERGY_WEIGHT = 0.01


def _one_step(start_probs, energy_weight, action):
    env = envs.make("getup_baseline", config_overrides={**SMALL, "start_probs": start_probs,
                                                         "reward.scales.energy": -energy_weight})
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    return env, jax.jit(env.step)(state, action)


def test_a_negative_energy_scale_subtracts_the_seeds_energy_cost():
    action = jnp.full(23, 0.3)          # targets away from the fallen pose: the motors work
    env0, plain = _one_step([1.0, 0.0, 0.0], 0.0, action)
    env1, tuned = _one_step([1.0, 0.0, 0.0], ENERGY_WEIGHT, action)
    cost = float(G.energy_cost(tuned.data.qvel[6:], tuned.data.actuator_force, env1._tau_limit))
    assert cost > 1.0                   # [rad/s]: the step moved joints against torque
    assert float(plain.metrics["reward/energy"]) == 0.0
    assert float(tuned.metrics["reward/energy"]) == pytest.approx(-ENERGY_WEIGHT * cost, rel=1e-5)
    # same start, same physics: the reward differs by the cost alone (× ctrl_dt, as every term)
    assert float(plain.reward) == pytest.approx(float(plain.metrics["reward/height"]) * env0.dt, rel=1e-5)
    assert float(tuned.reward) == pytest.approx((float(tuned.metrics["reward/height"]) - ENERGY_WEIGHT * cost)
                                                * env1.dt, rel=1e-4)


def test_standing_starts_count_as_success_but_not_from_fallen():
    _, standing = _one_step([0.0, 0.0, 1.0], 0.0, jnp.zeros(23))
    assert int(standing.info["start_kind"]) == 2
    assert float(standing.metrics["success"]) == 1.0 and float(standing.metrics["success_from_fallen"]) == 0.0
    _, fallen = _one_step([1.0, 0.0, 0.0], 0.0, jnp.zeros(23))
    assert int(fallen.info["start_kind"]) == 0
    assert float(fallen.metrics["success_from_fallen"]) == float(fallen.metrics["success"])


def test_default_is_the_seeds_baseline():
    cfg = envs.default_config("getup_baseline")
    assert list(cfg.start_probs) == [1.0, 0.0, 0.0] and cfg.reward.scales.to_dict() == {"height": 1.0, "energy": 0.0}
