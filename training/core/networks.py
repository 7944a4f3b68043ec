"""The PPO networks of every run: brax's, with the sampling std scaled, and a frozen-policy variant for
the critic warm-up. The factory's keywords are what brax's checkpoint network_config records."""
from __future__ import annotations

import functools

import jax
import numpy as np
from brax.training import distribution, networks, types
from brax.training.acme import running_statistics
from brax.training.agents.ppo import networks as brax_ppo_networks
from brax.training.types import identity_observation_preprocessor

from training.envs.policy_files import ACTIVATION  # noqa: F401 (the networks' activation, brax's default)

NORMALIZER_COUNT = 2 ** 32   # samples a held normaliser counts (float32 reads it to 512: the BC decay's step)
MIN_STD = 1e-3            # brax NormalTanhDistribution's min_std: scale = softplus(raw) + MIN_STD


def ppo_networks_with_std_scale(observation_size, action_size, preprocess_observations_fn=None,
                                policy_hidden_layer_sizes=(512, 256, 128), value_hidden_layer_sizes=(512, 256, 128),
                                policy_obs_key="state", value_obs_key="state", policy_std_scale: float = 1.0,
                                policy_distribution: str = "tanh_normal", init_noise_std: float = 1.0):
    """brax's make_ppo_networks, its tanh-normal policy's std multiplied by policy_std_scale (brax's own
    NormalTanhDistribution var_scale; make_ppo_networks does not pass it on). Only sampling and the PPO
    log-probabilities change: the parameters, checkpoints and exported means are brax's. Every keyword is
    named here so that brax's checkpoint network_config records it. policy_distribution "normal" (the student's
    fine-tune, distill/finetune.py): no tanh, a learned state-independent std starting at init_noise_std."""
    nets = brax_ppo_networks.make_ppo_networks(
        observation_size, action_size,
        preprocess_observations_fn=preprocess_observations_fn or identity_observation_preprocessor,
        policy_hidden_layer_sizes=policy_hidden_layer_sizes, value_hidden_layer_sizes=value_hidden_layer_sizes,
        policy_obs_key=policy_obs_key, value_obs_key=value_obs_key,
        **({"distribution_type": "normal", "noise_std_type": "log", "init_noise_std": init_noise_std}
           if policy_distribution == "normal" else {}))
    if policy_std_scale == 1.0 or policy_distribution == "normal":
        return nets
    return nets.replace(parametric_action_distribution=distribution.NormalTanhDistribution(
        event_size=action_size, var_scale=policy_std_scale))


def network_factory(cfg):
    """The run's network factory from its PPO config (training/ppo/train.py ppo_config)."""
    return functools.partial(
        ppo_networks_with_std_scale,
        policy_hidden_layer_sizes=tuple(cfg.policy_hidden_layer_sizes),
        value_hidden_layer_sizes=tuple(cfg.value_hidden_layer_sizes),
        policy_obs_key=cfg.policy_obs_key, value_obs_key=cfg.value_obs_key,
        policy_std_scale=float(cfg.policy_std_scale), policy_distribution=cfg.policy_distribution,
        init_noise_std=float(cfg.init_noise_std))


def frozen_policy_factory(factory):
    """The same networks, with no gradient into the policy's parameters: PPO's loss then trains only the
    critic (value warm-up). Sampling, checkpoints and exports are unchanged."""

    def make(*args, **kwargs):
        nets = factory(*args, **kwargs)
        policy = nets.policy_network
        frozen = networks.FeedForwardNetwork(
            init=policy.init,
            apply=lambda processor, params, *a, **k: policy.apply(processor, jax.lax.stop_gradient(params), *a, **k))
        return nets.replace(policy_network=frozen)
    return make


def held_normalizer(stats: dict, count: int):
    """brax's running statistics at given {observation key: (mean, std)}, counted `count` times: a count that
    large (NORMALIZER_COUNT) holds them, as a network trained on them needs, against the updates of its new run."""
    return running_statistics.RunningStatisticsState(
        count=types.UInt64(hi=np.uint32(count >> 32), lo=np.uint32(count & 0xFFFFFFFF)),
        mean={k: np.asarray(m, np.float32) for k, (m, _) in stats.items()},
        summed_variance={k: np.square(np.asarray(s, np.float32)) * count for k, (_, s) in stats.items()},
        std={k: np.asarray(s, np.float32) for k, (_, s) in stats.items()})


def tanh_normal_policy(layers: dict, init_std: float) -> dict:
    """A brax tanh-normal policy MLP fitted by behaviour cloning (its scale half never trained) as a PPO policy's
    first params: the layers as they are, the last layer's scale half giving the pre-tanh std init_std everywhere."""
    if not init_std > MIN_STD:
        raise ValueError(f"ppo.init_noise_std must be > {MIN_STD} (the sampling std), got {init_std}")
    inner = {k: {n: np.array(v) for n, v in layer.items()} for k, layer in layers["params"].items()}
    last = inner[f"hidden_{len(inner) - 1}"]
    half = last["bias"].shape[0] // 2
    last["kernel"][:, half:] = 0.0
    last["bias"][half:] = np.log(np.expm1(init_std - MIN_STD))
    return {"params": inner}
