"""RL from the imitation policy (DAPG, arXiv 1709.10087: behaviour-cloning init, then policy gradient with a demo
term whose weight decays): PPO on a getup task from the DAgger learner's artifact, plus a behaviour-cloning term on
the aggregated planner data (the demonstrations and every stored DAgger round), so PPO changes what the planner's
labels could not teach (holding §4.8's gate) without unlearning the rise they did teach.

Start. The DAgger artifact is brax's tanh-normal policy MLP (learner.py): its layers become the PPO policy as they
are; the scale half of the last layer, which the fit never trained, is reset to one state-independent sampling std
(ppo.init_noise_std, pre-tanh). The observation normaliser is the artifact's mean and std, held (counted
NORMALIZER_COUNT times, so a run's samples move it by well under 1 %): the DAgger data are the learner's own
states already, and a normaliser that moved under the policy would change what it does (training/LESSONS.md).
The critic's extra inputs (velocities, heights, torque shares, contacts: all of order 1) are held at mean 0 and
std 1. The critic starts fresh (ppo.value_warmup_steps: ppo/train.py).
BC term, added to brax's PPO loss:
    w(n) · mean over bc_batch random pairs of Σ_joints (tanh(μ(obs)) − label)²
    w(n) = imitation.bc_weight · max(0, 1 − n / imitation.bc_decay_steps)
with label the action of the planner's joint targets under the getup action map (the DAgger fit's own labels)
and n the env steps of this fine-tune (the normaliser's sample count minus the count it started from)."""
from __future__ import annotations

import contextlib
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from brax.training.agents.ppo import losses as ppo_losses

from training.core import checkpoints
from training.core.checkpoints import repo_path
from training.core.extension import PPOExtension
from training.core.networks import NORMALIZER_COUNT, held_normalizer, tanh_normal_policy
from training.distill.finetune import bc_weight, sample_count
from training.envs.policy_files import artifact_params
from training.imitation import config as campaign_files
from training.imitation import dataset
from training.imitation.learner import targets_to_labels

# the keys that make a PPO stage this fine-tune: a toy run keeps them (recipes/runner.py)
LEARNER_KEYS = ("ppo.imitation.",)


def uses_imitation(ppo_cfg) -> bool:
    return float(ppo_cfg.imitation.bc_weight) > 0


def is_artifact(path) -> bool:
    return Path(path).suffix == ".safetensors"


def read_learner(path) -> dict:
    """The DAgger learner an artifact holds: {"path", "layers": brax policy params, "mean", "std"}."""
    layers, mean, std, manifest = artifact_params(path)
    if manifest.get("output_rule") not in (None, "tanh_normal"):
        raise ValueError(f"{path}: a fine-tune from an artifact needs brax's tanh-normal policy, "
                         f"not output rule {manifest.get('output_rule')!r}")
    return {"path": str(path), "layers": layers, "mean": mean, "std": std}


def normalizer_state(mean: np.ndarray, std: np.ndarray, count: int, observation_size: dict):
    """brax's running statistics at the learner's (mean, std) for "state", counted `count` times; the critic's
    "privileged_state" starts with the same actor observation, its extras at mean 0, std 1."""
    n = int(observation_size["state"][0])
    if mean.shape != (n,):
        raise ValueError(f"the artifact's observation has {mean.shape[0]} entries, the task's {n}")
    extra = int(observation_size["privileged_state"][0]) - n
    stats = {"state": (mean, std),
             "privileged_state": (np.concatenate([mean, np.zeros(extra, np.float32)]),
                                  np.concatenate([std, np.ones(extra, np.float32)]))}
    return held_normalizer(stats, count)


def _campaign_of(init) -> Path:
    """The DAgger campaign of what a run starts from: a DAgger artifact's folder, or, for a PPO run or its export
    (a fine-tune going on from another), that run's own campaign."""
    path = repo_path(init) if init else None
    if path is not None and is_artifact(path):
        if not (path.parent / checkpoints.RUN_STATE).exists():
            return path.parent
        path = path.parent
    run = path.parent.parent if path is not None and path.parent.name == checkpoints.CHECKPOINT_DIR else path
    try:
        state = checkpoints.load_run_state(run)
    except (OSError, ValueError, TypeError) as e:
        raise ValueError(f"ppo.imitation.campaign is empty and the run does not start from a DAgger artifact or a "
                         f"fine-tune of one ({init!r}: {e})") from e
    named = state["ppo_config"].get("imitation", {}).get("campaign", "")
    return repo_path(named) if named else _campaign_of(state.get("init"))


def pin_campaign(ppo_cfg, init) -> None:
    """A new run whose BC term reads the DAgger campaign of what it starts from names that campaign in its own
    config: its run state then resumes where its init is not kept (a campaign keeps only each stage's newest)."""
    if uses_imitation(ppo_cfg) and ppo_cfg.imitation.demos and not ppo_cfg.imitation.campaign:
        ppo_cfg.imitation.campaign = checkpoints.repo_relative(_campaign_of(init))


def planner_pairs(ppo_cfg, init, action_map: dict) -> tuple[np.ndarray, np.ndarray]:
    """(observations, label actions) of the DAgger campaign's aggregate: the demonstrations and every round it
    stored, labels through the getup action map ({"default_pose", "action_scale"} [rad]); `init`: the path the
    run starts from (its folder is the campaign where ppo.imitation.campaign is "")."""
    t = ppo_cfg.imitation
    if not t.demos:
        raise ValueError("ppo.imitation.demos must name the planner's demonstrations (the DAgger round 0)")
    campaign = repo_path(t.campaign) if t.campaign else _campaign_of(init)
    data = campaign / campaign_files.DATA
    collected = data / campaign_files.COLLECTED
    if not collected.exists():
        raise ValueError(f"{campaign}: not a DAgger campaign (no {campaign_files.DATA}/{campaign_files.COLLECTED})")
    rounds = 1 + max((int(k) for k in json.loads(collected.read_text())["rounds"]), default=0)
    obs, q = dataset.aggregate(data, repo_path(t.demos), rounds, int(t.first_round))
    if len(obs) == 0:
        raise ValueError(f"{campaign}: no labels in rounds {int(t.first_round)} … {rounds - 1} "
                         "(ppo.imitation.first_round) for the BC term")
    return obs, targets_to_labels(q, action_map["default_pose"], action_map["action_scale"])


class ImitationFinetune(PPOExtension):
    """The hooks of RL from the imitation policy: the DAgger artifact as the first policy and the decaying BC term
    on the planner's data (module docstring)."""

    def __init__(self, ppo_cfg):
        self._cfg = ppo_cfg
        self._pairs = None

    def _data(self, env, init) -> tuple[np.ndarray, np.ndarray]:
        if self._pairs is None:
            fields = env.manifest_fields()
            action_map = {k: np.asarray(fields[k]) for k in ("default_pose", "action_scale")}
            self._pairs = planner_pairs(self._cfg, init, action_map)
        return self._pairs

    def initial_params(self, restored, env=None):
        if not isinstance(restored, dict) or "layers" not in restored:
            return restored                      # a PPO checkpoint (or none): as it is
        if env is None:
            raise ValueError("a fine-tune from a DAgger artifact needs the task's observation sizes")
        return [normalizer_state(restored["mean"], restored["std"], NORMALIZER_COUNT, env.observation_size),
                tanh_normal_policy(restored["layers"], float(self._cfg.init_noise_std)), None]

    def state_fields(self, params) -> dict:
        return {"bc_count_start": float(sample_count(params[0])) if params else 0.0}

    def loss_term(self, env, state: dict):
        pairs = self._data(env, state.get("init")) if uses_imitation(self._cfg) else None
        return imitation_term(self._cfg, pairs, float(state.get("bc_count_start", 0.0)))


def bc_loss(ppo_network, policy_params, normalizer_params, obs, labels, sizes: dict, policy_key: str = "state"):
    """mean over the pairs of Σ_joints (tanh(μ(obs)) − label)²: the DAgger fit's regression (learner.fit, there a
    mean over the joints) on the PPO policy. sizes: the observation's entries per key (the others are zeros)."""
    x = {k: obs if k == policy_key else jnp.zeros((obs.shape[0], n), jnp.float32) for k, n in sizes.items()}
    logits = ppo_network.policy_network.apply(normalizer_params, policy_params, x)
    mean = ppo_network.parametric_action_distribution.mode(logits)
    return jnp.mean(jnp.sum(jnp.square(mean - labels), axis=-1))


@contextlib.contextmanager
def imitation_term(ppo_cfg, pairs, count_start: float):
    """While open, brax's PPO loss carries the BC term on `pairs` (module docstring); a no-op without one."""
    if pairs is None:
        yield
        return
    t = ppo_cfg.imitation
    weight, decay, batch = float(t.bc_weight), int(t.bc_decay_steps), int(t.bc_batch)
    obs, labels = jnp.asarray(pairs[0], jnp.float32), jnp.asarray(pairs[1], jnp.float32)
    ppo_loss = ppo_losses.compute_ppo_loss

    def loss(params, normalizer_params, data, rng, ppo_network, **kwargs):
        total, metrics = ppo_loss(params, normalizer_params, data, rng, ppo_network, **kwargs)
        idx = jax.random.randint(jax.random.fold_in(rng, 1), (batch,), 0, obs.shape[0])
        bc = bc_loss(ppo_network, params.policy, normalizer_params, obs[idx], labels[idx],
                     {k: v.shape[-1] for k, v in data.observation.items()}, ppo_cfg.policy_obs_key)
        w = bc_weight(sample_count(normalizer_params, jnp) - count_start, weight, decay)
        return total + w * bc, {**metrics, "bc_loss": bc, "bc_weight": w}

    ppo_losses.compute_ppo_loss = loss
    try:
        yield
    finally:
        ppo_losses.compute_ppo_loss = ppo_loss
