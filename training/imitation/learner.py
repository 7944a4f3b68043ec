"""The learner: brax's tanh-normal policy MLP (the getup experts' network and action map), fitted to the planner's
labels by regression, run in NumPy in the rollouts and exported as a runtime artifact.

Its parameters are brax's ({'params': {'hidden_i': {kernel, bias}}}, 2·23 outputs: loc, then the scale half that
only PPO uses), so the fit's policy is the initial policy of a PPO fine-tune and exports through
training/export/brax.py as any getup expert does. Observations are normalised by the demonstrations' mean and std,
fixed from round 0 on (a moving normaliser would move every later fit's inputs)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import optax

from common import observation as obsdef
from training.core.networks import ppo_networks_with_std_scale
from training.envs.policy_files import ACTIVATION, artifact_params, brax_policy_layers
from training.export.brax import export_brax_ppo

STD_FLOOR = 1e-3         # the normaliser's smallest std (a joint that never moved in the data)
ACTION_LIMIT = 0.999     # labels' actions are clipped inside tanh's range


@dataclass
class Learner:
    params: dict             # brax policy params (numpy)
    obs_mean: np.ndarray     # (52,)
    obs_std: np.ndarray
    default_pose: np.ndarray  # (23,) [rad]
    action_scale: np.ndarray  # (23,) [rad per unit]
    lo: np.ndarray           # joint ranges [rad]
    hi: np.ndarray

    def actions(self, obs: np.ndarray) -> np.ndarray:
        return obsdef.policy_forward(brax_policy_layers(self.params), obs, self.obs_mean, self.obs_std,
                                     ACTIVATION, "tanh_normal")

    def targets(self, obs: np.ndarray) -> np.ndarray:
        """Joint targets [rad] of (n, 52) observations, as the runtime maps the artifact's action."""
        q = obsdef.action_to_targets(self.default_pose, self.action_scale, self.actions(obs))
        return np.clip(q, self.lo, self.hi)

    def label_actions(self, q_des: np.ndarray) -> np.ndarray:
        """The action a policy of this map sends for joint targets q_des [rad] (the regression's labels)."""
        return targets_to_labels(q_des, self.default_pose, self.action_scale)

    def export(self, path: Path, manifest_fields: dict) -> str:
        norm = SimpleNamespace(mean=self.obs_mean, std=self.obs_std)
        return export_brax_ppo((norm, self.params), manifest_fields, path)


def targets_to_labels(q_des: np.ndarray, default_pose: np.ndarray, action_scale: np.ndarray) -> np.ndarray:
    """The actions of joint targets q_des [rad] under the getup action map, inside tanh's range."""
    return np.clip(obsdef.targets_to_action(default_pose, action_scale, q_des), -ACTION_LIMIT, ACTION_LIMIT)


def new_learner(obs: np.ndarray, hidden: list[int], seed: int, env_fields: dict, lo, hi) -> Learner:
    """A freshly initialised brax policy network, normalised by `obs`' statistics."""
    nets = ppo_networks_with_std_scale(obs.shape[1], len(lo), policy_hidden_layer_sizes=tuple(hidden))
    params = jax.tree.map(np.asarray, nets.policy_network.init(jax.random.PRNGKey(seed)))
    return Learner(params=params, obs_mean=obs.mean(axis=0).astype(np.float32),
                   obs_std=np.maximum(obs.std(axis=0), STD_FLOOR).astype(np.float32),
                   default_pose=np.asarray(env_fields["default_pose"], np.float64),
                   action_scale=np.broadcast_to(np.asarray(env_fields["action_scale"], np.float64), (len(lo),)),
                   lo=np.asarray(lo), hi=np.asarray(hi))


def load_learner(artifact: Path, like: Learner) -> Learner:
    """The learner an artifact of `export` holds (this fit's or a PPO fine-tune's of it), with the action map of
    `like`; ValueError when its network or action map is not `like`'s."""
    params, mean, std, manifest = artifact_params(artifact)
    shapes = {k: v["kernel"].shape for k, v in params["params"].items()}
    want = {k: v["kernel"].shape for k, v in like.params["params"].items()}
    if shapes != want:
        raise ValueError(f"{artifact}: its layers {sorted(shapes.values())} are not the learner's "
                         f"{sorted(want.values())}")
    for key, ours in (("default_pose", like.default_pose), ("action_scale", like.action_scale)):
        theirs = np.broadcast_to(np.asarray(manifest.get(key, np.nan), np.float64), np.shape(ours))
        if not np.allclose(theirs, ours, atol=1e-6):
            raise ValueError(f"{artifact}: its {key} is not the getup action map's")
    return Learner(params=params, obs_mean=mean, obs_std=std, default_pose=like.default_pose,
                   action_scale=like.action_scale, lo=like.lo, hi=like.hi)


def fit(learner: Learner, obs: np.ndarray, actions: np.ndarray, cfg, seed: int) -> tuple[Learner, list[float]]:
    """cfg.steps of Adam on mean((tanh(loc) − action)²) over shuffled batches, from the learner's params. Returns
    the fitted learner and the loss per pass over the data as a share of the actions' variance."""

    x = (obs.astype(np.float32) - learner.obs_mean) / learner.obs_std
    y = actions.astype(np.float32)
    n_layers = len(learner.params["params"])
    action_size = y.shape[1]

    def forward(params, xb):
        h = xb
        for i in range(n_layers):
            layer = params["params"][f"hidden_{i}"]
            h = h @ layer["kernel"] + layer["bias"]
            if i < n_layers - 1:
                h = jax.nn.swish(h)
        return jnp.tanh(h[:, :action_size])

    lr = float(cfg.learning_rate)
    steps = int(cfg.steps)
    opt = optax.adam(optax.cosine_decay_schedule(lr, max(steps, 1), alpha=float(cfg.final_lr_share)))

    @jax.jit
    def step(params, opt_state, xb, yb):
        loss, grad = jax.value_and_grad(lambda p: jnp.mean(jnp.square(forward(p, xb) - yb)))(params)
        updates, opt_state = opt.update(grad, opt_state, params)
        return optax.apply_updates(params, updates), opt_state, loss

    params = jax.tree.map(jnp.asarray, learner.params)
    opt_state = opt.init(params)
    rng = np.random.default_rng(seed)
    bs = min(int(cfg.batch_size), len(x))
    var = float(np.mean(np.var(y, axis=0))) + 1e-12
    per_pass = max(len(x) // bs, 1)
    history, losses, order = [], [], rng.permutation(len(x))
    for k in range(steps):
        j = k % per_pass
        if j == 0 and k > 0:
            history.append(float(np.mean(losses)) / var)
            losses, order = [], rng.permutation(len(x))
        params, opt_state, loss = step(params, opt_state, x[order[j * bs:(j + 1) * bs]], y[order[j * bs:(j + 1) * bs]])
        losses.append(loss)
    history.append(float(np.mean(np.asarray(losses))) / var)
    fitted = Learner(params=jax.tree.map(np.asarray, params), obs_mean=learner.obs_mean, obs_std=learner.obs_std,
                     default_pose=learner.default_pose, action_scale=learner.action_scale, lo=learner.lo,
                     hi=learner.hi)
    return fitted, history
