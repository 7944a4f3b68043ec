"""training/core/networks.py: the sampling-std scale (policy_std_scale) and the critic-only warm-up networks
(value_warmup_steps), each through brax's own distribution and PPO loss."""
import numpy as np


def test_policy_std_scale_scales_only_the_sampling_std():
    import jax.numpy as jnp

    from training.core.networks import network_factory
    from training.ppo.configs import ppo_config
    cfg = ppo_config("getup", "toy")
    params = jnp.linspace(-1.0, 1.0, 2 * 23)
    stds = []
    for scale in (1.0, 0.25):
        cfg.policy_std_scale = scale
        nets = network_factory(cfg)({"state": (52,), "privileged_state": (60,)}, 23)
        dist = nets.parametric_action_distribution.create_dist(params)
        stds.append(np.asarray(dist.scale))
        assert np.allclose(np.asarray(dist.loc), np.asarray(params[:23]))
    np.testing.assert_allclose(stds[1], 0.25 * stds[0], rtol=1e-6)
    assert ppo_config("joystick").policy_std_scale == 1.0      # brax's std unless a run asks otherwise


def test_value_warmup_networks_train_only_the_critic():
    """PPO's loss through the frozen-policy networks: no gradient reaches the policy, the critic's is the same."""
    import jax
    import jax.numpy as jnp
    from brax.training import types
    from brax.training.acme import running_statistics
    from brax.training.agents.ppo import losses

    from training.core.networks import frozen_policy_factory, network_factory
    from training.ppo.configs import ppo_config
    cfg = ppo_config("getup", "toy")
    obs_size, act, batch, unroll = {"state": (6,), "privileged_state": (8,)}, 3, 4, 5
    key = jax.random.PRNGKey(0)
    obs = {k: jax.random.normal(key, (batch, unroll, *v)) for k, v in obs_size.items()}
    data = types.Transition(
        observation=obs, action=jnp.zeros((batch, unroll, act)),
        reward=jnp.linspace(-1.0, 1.0, batch * unroll).reshape(batch, unroll),
        discount=jnp.ones((batch, unroll)), next_observation=obs,
        extras={"state_extras": {"truncation": jnp.zeros((batch, unroll))},
                "policy_extras": {"raw_action": 0.3 * jnp.ones((batch, unroll, act)),
                                  "log_prob": -jnp.ones((batch, unroll)),
                                  "distribution_params": jnp.zeros((batch, unroll, 2 * act))}})
    grads = {}
    for name, factory in (("ppo", network_factory(cfg)), ("warmup", frozen_policy_factory(network_factory(cfg)))):
        nets = factory(obs_size, act, preprocess_observations_fn=running_statistics.normalize)
        params = losses.PPONetworkParams(policy=nets.policy_network.init(jax.random.PRNGKey(1)),
                                         value=nets.value_network.init(jax.random.PRNGKey(2)))
        norm = running_statistics.init_state({k: jax.ShapeDtypeStruct(v, jnp.float32) for k, v in obs_size.items()})
        loss = lambda p: losses.compute_ppo_loss(p, norm, data, key, nets, entropy_cost=0.01)[0]  # noqa: E731
        grads[name] = jax.grad(loss)(params)
    norm_of = lambda tree: float(sum(jnp.sum(jnp.abs(x)) for x in jax.tree_util.tree_leaves(tree)))  # noqa: E731
    assert norm_of(grads["ppo"].policy) > 0.0
    assert norm_of(grads["warmup"].policy) == 0.0
    for a, b in zip(jax.tree_util.tree_leaves(grads["ppo"].value), jax.tree_util.tree_leaves(grads["warmup"].value)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-7)
