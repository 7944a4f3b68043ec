"""The sagittal, mirrored action space (training/envs/sagittal.py) the kneel task's backplay learns in."""
from __future__ import annotations

import numpy as np
import pytest

from common import model as t1model
from messages.contract import JOINT_NAMES, NUM_JOINTS, joint_index
from training import envs
from training.envs import sagittal


def test_each_pitch_value_drives_both_sides_and_nothing_else():
    m = sagittal.expansion()
    assert m.shape == (NUM_JOINTS, len(sagittal.PITCH_JOINTS))
    full = m @ np.arange(1.0, len(sagittal.PITCH_JOINTS) + 1)
    for j, name in enumerate(sagittal.PITCH_JOINTS):
        if name == "Head_pitch":
            assert full[joint_index(name)] == j + 1
        else:
            assert full[joint_index(f"Left_{name}")] == full[joint_index(f"Right_{name}")] == j + 1
    held = [n for n in JOINT_NAMES if not any(n.endswith(p) for p in sagittal.PITCH_JOINTS)]
    assert held and all(full[joint_index(n)] == 0.0 for n in held)        # roll and yaw keep home


def test_the_kneel_is_in_the_sagittal_space():
    """The kneel keyframe differs from home only in mirrored pitch joints: the reduced policy can reach it."""
    model = t1model.load_model()
    delta = t1model.kneel_pose(model) - t1model.default_pose(model)
    m = sagittal.expansion()
    reduced = np.linalg.lstsq(m, delta, rcond=None)[0]
    np.testing.assert_allclose(m @ reduced, delta, atol=1e-9)


def test_the_kneel_task_expands_the_policy_action():
    env = envs.make("getup_kneel", config_overrides={"fallen.bank_starts": 2, "action_space": "sagittal"})
    assert env.action_size == len(sagittal.PITCH_JOINTS)
    a = np.linspace(-0.5, 0.5, env.action_size)
    np.testing.assert_allclose(np.asarray(env.full_action(a)), sagittal.expansion() @ a, rtol=1e-6)
    full = envs.make("getup_kneel", config_overrides={"fallen.bank_starts": 2})
    assert full.action_size == NUM_JOINTS
    with pytest.raises(ValueError, match="action_space 'mirrored' unknown"):
        envs.make("getup_kneel", config_overrides={"fallen.bank_starts": 2, "action_space": "mirrored"})


def test_a_sagittal_policy_exports_as_the_same_policy_over_the_23_joints(tmp_path):
    """The artifact (the runtime's contract) acts as the env does: brax's deterministic action, expanded."""
    import jax
    import jax.numpy as jnp
    from brax.training.acme import running_statistics, specs
    from brax.training.agents.ppo import networks as ppo_networks

    from common import artifact
    from common import observation as ob
    from training.export import brax as export

    obs_size, n = ob.observation_size(ob.TERMS_GETUP), len(sagittal.PITCH_JOINTS)
    nets = ppo_networks.make_ppo_networks(obs_size, n, preprocess_observations_fn=running_statistics.normalize,
                                          policy_hidden_layer_sizes=(32, 16), value_hidden_layer_sizes=(8,))
    k_pol, k_val, k_obs = jax.random.split(jax.random.PRNGKey(0), 3)
    normalizer = running_statistics.init_state(specs.Array((obs_size,), jnp.float32))
    params = (normalizer, nets.policy_network.init(k_pol), nets.value_network.init(k_val))
    policy, rule = export.exported_policy(params[1], {"policy_distribution": "tanh_normal"},
                                          {"action_space": "sagittal"})
    path = tmp_path / "sagittal.safetensors"
    export.export_brax_ppo((params[0], policy), {"name": "sagittal", "activation": "swish", "output_rule": rule,
                                                 "obs_terms": [list(t) for t in ob.TERMS_GETUP]}, path)
    layers, mean, std, manifest = artifact.read_artifact(path)
    obs = np.asarray(jax.random.normal(k_obs, (16, obs_size)), np.float32)
    brax_action = np.asarray(ppo_networks.make_inference_fn(nets)(params, deterministic=True)(
        jnp.asarray(obs), jax.random.PRNGKey(1))[0])
    runtime_action = ob.mlp_forward(layers, ob.normalize(obs, mean, std), manifest["activation"],
                                    manifest["output_rule"])
    np.testing.assert_allclose(runtime_action, brax_action @ sagittal.expansion().T, atol=1e-5)
    with pytest.raises(ValueError, match="sagittal: the policy's output layer has 46 outputs"):
        sagittal.expand_policy(jax.tree_util.tree_map(np.asarray, ppo_networks.make_ppo_networks(
            obs_size, NUM_JOINTS, policy_hidden_layer_sizes=(8,)).policy_network.init(k_pol)))
