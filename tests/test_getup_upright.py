"""The composite's upright member inside the getup env (training/envs/upright.py, getup config upright_policy):
above the switch height the joystick artifact drives and the getup action is ignored; below it the getup
action is applied and the member reads it in its own map, as artifact_policy.CompositePolicy."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from training import envs
from training.envs import getup_rewards as G
from training.artifact_policy import ArtifactPolicy
from messages.contract import WAIST_SWITCH_HEIGHT_M

JOYSTICK = "policies/joystick/joystick.safetensors"
GETUP = "policies/getup_knockdown/getup_knockdown.safetensors"
STANDING_ONLY = {"backend": "cpu", "start_probs": [0.0, 0.0, 1.0]}   # no fallen-start precomputation


def _rollout(overrides, action, ticks, n=2):
    env = envs.make("getup", config_overrides=overrides)
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(0), n))
    for _ in range(ticks):
        state = step(state, jnp.broadcast_to(action, (n, 23)))
    return env, state


@pytest.mark.slow
def test_standing_robot_is_driven_by_the_upright_member():
    """A standing start: the joystick expert holds the robot up whatever the getup action; without the member
    the same action (every joint at +1) throws it over."""
    ticks = 100   # 2 s at 50 Hz
    _, held = _rollout({**STANDING_ONLY, "upright_policy": JOYSTICK, "gate_latches": False}, jnp.ones(23), ticks)
    _, alone = _rollout(STANDING_ONLY, jnp.ones(23), ticks)
    assert np.all(np.asarray(held.info["trunk_height"]) > 0.6)
    assert np.all(np.asarray(held.info["waist_height"]) >= WAIST_SWITCH_HEIGHT_M)
    # its stand is off the seed's 0.573° gate, and counts as past the kneel (upright.py)
    assert np.all(np.asarray(G.up_error(held.info["up"])) > G.GATE_UP_ERROR)
    assert np.all(np.asarray(held.info["gate"]))
    assert np.all(np.asarray(alone.info["trunk_height"]) < 0.5)


@pytest.mark.slow
def test_below_the_switch_the_getup_action_is_applied_and_the_member_reads_it():
    env = envs.make("getup", config_overrides={"backend": "cpu", "start_probs": [0.0, 1.0, 0.0],
                                               "upright_policy": JOYSTICK})
    state = jax.jit(env.reset)(jax.random.PRNGKey(1))      # at the kneel: waist below the switch
    assert float(state.info["waist_height"]) < WAIST_SWITCH_HEIGHT_M
    action = jnp.linspace(-0.3, 0.3, 23)
    info = dict(state.info)
    q_des = env._joint_targets(state, action, info)
    assert np.allclose(q_des, env.motor_targets(action), atol=1e-6)
    own = ArtifactPolicy.load(JOYSTICK).in_own_map(q_des)
    assert np.allclose(info["upright_last_act"], own, atol=1e-6)
    assert float(jnp.max(jnp.abs(info["upright_last_act"]))) <= 1.0


@pytest.mark.parametrize("path, why", [(GETUP, "reads the getup observation"),
                                       ("policies/no_such.safetensors", "no_such"),
                                       ("policies/getup_knockdown", r"\.safetensors")])
def test_upright_policy_must_be_a_joystick_artifact(path, why):
    with pytest.raises((ValueError, FileNotFoundError, OSError), match=why):
        envs.make("getup", config_overrides={**STANDING_ONLY, "upright_policy": path})
