"""Where a CPU-backend PPO env step goes besides the physics (`make bench-train`'s profile rows): each part timed
alone at the run's real sizes, then charged per env step, so that × the run's env-steps/s it is that part's share
of the run's wall time.

* env JAX: the env's own jitted step (rewards, observation, resets' bookkeeping) for the preset's envs, minus the
  C physics and the callback's copies inside it (cpu_backend.PROFILE);
* policy pass: the actor on the preset's envs' observations, once per control step;
* update: one SGD step of brax PPO's loss (policy and value networks as the run's, Adam) on one minibatch,
  num_updates_per_batch × num_minibatches of them per batch_size × num_minibatches × unroll_length env steps.
The rest of the run (GAE, the normaliser, metrics, PPO's loop) is what these leave."""
from __future__ import annotations

import time

REPEATS = 8   # timed calls of each part (after a compiling one)


def _timed(fn, *args) -> float:
    """Seconds per call of jitted fn, after a first (compiling) call."""
    import jax
    jax.block_until_ready(fn(*args))
    t0 = time.perf_counter()
    for _ in range(REPEATS):
        out = fn(*args)
    jax.block_until_ready(out)
    return (time.perf_counter() - t0) / REPEATS


def env_jax_s(env, num_envs: int) -> float:
    """Seconds per env step of the env's JAX code around the C physics."""
    import jax
    import jax.numpy as jnp

    from training.envs import cpu_backend
    step = jax.jit(jax.vmap(env.step))
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), num_envs))
    action = jnp.zeros((num_envs, env.action_size))
    jax.block_until_ready(step(state, action))
    cpu_backend.PROFILE.reset()
    t0 = time.perf_counter()
    for _ in range(REPEATS):
        state = step(state, action)
    jax.block_until_ready(state.obs)
    host = cpu_backend.PROFILE.physics_s + cpu_backend.PROFILE.copies_s
    return (time.perf_counter() - t0 - host) / (REPEATS * num_envs)


def _networks(env, cfg):
    import jax
    import jax.numpy as jnp
    from brax.training.acme import running_statistics

    from training.core import networks as ppo_networks
    sizes = {k: tuple(v) for k, v in env.observation_size.items()}
    nets = ppo_networks.network_factory(cfg)(sizes, env.action_size,
                                              preprocess_observations_fn=running_statistics.normalize)
    norm = running_statistics.init_state({k: jax.ShapeDtypeStruct(v, jnp.float32) for k, v in sizes.items()})
    return nets, norm, sizes


def policy_pass_s(env, cfg) -> float:
    """Seconds per env step of the actor's forward pass (a batch of the preset's envs)."""
    import jax
    import jax.numpy as jnp
    nets, norm, sizes = _networks(env, cfg)
    params = nets.policy_network.init(jax.random.PRNGKey(0))
    obs = {k: jnp.ones((cfg.num_envs, *v)) for k, v in sizes.items()}
    return _timed(jax.jit(lambda o: nets.policy_network.apply(norm, params, o)), obs) / cfg.num_envs


def update_s(env, cfg) -> float:
    """Seconds per env step of PPO's SGD (loss, gradients, Adam) at the run's minibatch size and networks."""
    import jax
    import jax.numpy as jnp
    import optax
    from brax.training import types
    from brax.training.agents.ppo import losses
    nets, norm, sizes = _networks(env, cfg)
    key = jax.random.PRNGKey(0)
    params = losses.PPONetworkParams(policy=nets.policy_network.init(key), value=nets.value_network.init(key))
    optimizer = optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm), optax.adam(cfg.learning_rate))
    lead = (cfg.batch_size, cfg.unroll_length)
    obs = {k: jax.random.normal(key, (*lead, *v)) for k, v in sizes.items()}
    dist = nets.parametric_action_distribution
    logits = jax.random.normal(key, (*lead, dist.param_size))
    data = types.Transition(
        observation=obs, action=jax.random.normal(key, (*lead, env.action_size)), reward=jnp.ones(lead),
        discount=jnp.ones(lead), next_observation=obs,
        extras={"policy_extras": {"raw_action": jax.random.normal(key, (*lead, env.action_size)),
                                  "log_prob": jnp.zeros(lead), "distribution_params": logits},
                "state_extras": {"truncation": jnp.zeros(lead)}})

    def loss(p, d, k):
        return losses.compute_ppo_loss(p, norm, d, k, ppo_network=nets, entropy_cost=cfg.entropy_cost,
                                       discounting=cfg.discounting, reward_scaling=cfg.reward_scaling,
                                       clipping_epsilon=cfg.clipping_epsilon, normalize_advantage=True)

    @jax.jit
    def sgd_step(p, opt_state, d, k):
        grads, _ = jax.grad(loss, has_aux=True)(p, d, k)
        updates, opt_state = optimizer.update(grads, opt_state, p)
        return optax.apply_updates(p, updates), opt_state

    per_minibatch = _timed(sgd_step, params, optimizer.init(params), data, key)
    steps_per_update = cfg.batch_size * cfg.num_minibatches * cfg.unroll_length
    return per_minibatch * cfg.num_updates_per_batch * cfg.num_minibatches / steps_per_update


def profile(task: str, preset: str = "cpu") -> dict[str, float]:
    """{part: seconds per env step} of a `preset` run of `task` (module docstring)."""
    from training import envs
    from training.ppo import configs
    cfg = configs.ppo_config(task, preset)
    env = envs.make(task, config_overrides={"backend": "cpu"})
    return {"env JAX": env_jax_s(env, cfg.num_envs), "policy pass": policy_pass_s(env, cfg),
            "update": update_s(env, cfg)}
