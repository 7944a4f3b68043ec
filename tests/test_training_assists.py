"""The getup tasks' training aid (ours, not the seed's): the elastic harness (training/envs/assists.py). It changes
the model, so both backends get it; a policy trained with it is never exported as trained."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from training import envs


def _kneel_rise(stiffness_n_per_m: float) -> np.ndarray:
    """Trunk heights [m] over 3 s from the kneel, the targets at home (straight legs) from the first step."""
    cfg = envs.default_config("getup")
    cfg.stage, cfg.backend, cfg.harness.stiffness_n_per_m = "stage2", "cpu", stiffness_n_per_m
    env = envs.make("getup", config=cfg)
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    step = jax.jit(env.step)
    heights = []
    for _ in range(150):
        state = step(state, jnp.zeros(23))
        heights.append(float(state.info["trunk_height"]))
    return np.array(heights)


def test_harness_lets_straightening_legs_rise_from_the_kneel_and_is_off_by_default():
    from training.envs import assists
    from training.train import exported_as_trained
    # no harness: straight legs from the kneel throw the robot down (the stage-2 fall height is 0.35 m)
    assert _kneel_rise(0.0).min() < 0.35
    # the harness carries ~0.9 of the weight at the kneel (1100 N/m × 0.26 m): the same legs now rise
    assert _kneel_rise(1100.0)[-50:].min() > 0.55
    cfg = envs.default_config("getup")
    assert assists.stiffness(cfg) == 0.0 and envs.make("getup", config=cfg).mj_model.ntendon == 0
    cfg.harness.stiffness_n_per_m = 500.0
    for backend in ("cpu", "mjx"):
        cfg.backend = backend
        env = envs.make("getup", config=cfg)
        m = env.cpu_physics.model if backend == "cpu" else env.mj_model
        t = m.tendon(assists.TENDON).id
        assert m.tendon_stiffness[t] == 500.0
        np.testing.assert_allclose(m.tendon_lengthspring[t], [0.0, 3.0 - 0.67 - 0.3], atol=1e-6)
    assert not exported_as_trained(10_000_000, "cpu", cfg.to_dict())
    assert exported_as_trained(10_000_000, "cpu", envs.default_config("getup").to_dict())
    cfg.harness.stiffness_n_per_m = -1.0
    with pytest.raises(ValueError, match="stiffness"):
        envs.make("getup", config=cfg)
    cfg.harness.update(stiffness_n_per_m=500.0, slack_trunk_height_m=3.5)
    with pytest.raises(ValueError, match="anchor_height_m"):
        envs.make("getup", config=cfg)
