"""PPO training runs (brax ppo.train on the MJX envs of training/envs), resumable and time-boxed.

    python -m training train joystick --steps 200_000_000 --out runs/joystick --max-minutes 9 [--resume]
(a policy that ships comes from a recipe: `python -m training recipe NAME`, training/recipes/runner.py)

One call trains until the target env-step count or until --max-minutes would be overrun by the next
epoch, checkpointing after every epoch (brax's `policy_params_fn` hook: params arrive on the host there,
between two jitted epochs, so stopping there is clean). Every call exports the newest policy to
<out>/<name>.safetensors; --ship also copies it to policies/<name>/ and appends a row to its CARD.md.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import jax
import numpy as np
import tqdm
from brax.training import checkpoint as brax_checkpoint
from brax.training.agents.ppo import train as ppo
from ml_collections import config_dict

from common.artifact import read_artifact
from training import envs
from training.core import checkpoints, curves
from training.core import networks as ppo_networks
from training.core.backend import default_backend
from training.core.networks import ACTIVATION
from training.core.overrides import apply_overrides
from training.export import brax as export
from training.export.brax import export_brax_ppo, exported_as_trained, exported_policy, run_provenance
from training.ppo import extensions, migration
from training.ppo.configs import build_configs


@dataclass
class TrainResult:
    run_dir: Path
    artifact: Path
    env_steps: int
    target_steps: int
    minutes: float
    env_steps_per_s: float
    complete: bool


class _StopAtCheckpoint(Exception):
    """Raised from brax's policy_params_fn after a checkpoint when the time box is spent."""


class _Advanced(Exception):
    """Raised from brax's progress_fn when the run's advance_at criterion is met (after that step's checkpoint)."""


class _Ended(Exception):
    """Raised from brax's policy_params_fn after the checkpoint the run ends at (its end_at)."""


def _randomization(cfg, env=None, seed: int = 0):
    """brax's randomization_fn, or None. On the CPU backend the env randomises its C simulations itself
    (the same function, applied on the host) and brax gets None."""
    if env is not None and getattr(env, "backend", "mjx") == "cpu":
        if cfg.domain_randomization:
            env.randomize_on_host(envs.domain_randomize, seed)
        return None
    if not cfg.domain_randomization:
        return None
    return envs.domain_randomize


def make_env(task: str, env_cfg: config_dict.ConfigDict):
    if task not in envs.TASKS:
        raise ValueError(f"task: {task!r} is not one of {envs.TASKS}")
    return envs.make(task, config=env_cfg)


# What --config may change on --resume: how the run is computed and logged, not what it learns (a
# different task or learner is a new run: --from CHECKPOINT). num_envs has its own flag (--envs).
FIRST_EPOCH_MARGIN = 1.5   # next_epoch_estimate_s: the share an evaluation may add to an epoch's training time
RESUME_OVERRIDABLE = ("checkpoint_every_steps", "run_evals", "num_eval_envs", "training_metrics_steps")


def _check_resume_overrides(overrides: Sequence[str]) -> None:
    for item in overrides:
        key = item.split("=", 1)[0].split(".")[-1]
        if key not in RESUME_OVERRIDABLE:
            raise ValueError(f"--config {item!r} with --resume: only {', '.join(RESUME_OVERRIDABLE)} may "
                             "change in a resumed run (start a new run with --from to change the rest)")


def _check_batch_shape(cfg):
    if (cfg.batch_size * cfg.num_minibatches) % cfg.num_envs:
        raise ValueError(f"--envs {cfg.num_envs}: batch_size·num_minibatches = {cfg.batch_size}·"
                         f"{cfg.num_minibatches} must be a multiple of the number of envs")


def _epochs(cfg, steps: int) -> int:
    """num_evals for ppo.train: one epoch (= one checkpoint) per checkpoint_every_steps."""
    return max(2, math.ceil(steps / max(1, cfg.checkpoint_every_steps)) + 1)


def next_epoch_estimate_s(epoch_s: float, epoch_steps: int, sps: float | None, first_of_call: bool) -> float:
    """How long the next epoch (checkpoint to checkpoint) will take [s], for --max-minutes. A call's first
    epoch also holds the JIT compilation and the first evaluation (3–4 min of a GPU call's first 5 M steps,
    which then take 50 s): its successor is estimated from the measured throughput instead, with a margin for
    the evaluation, so a short call does not stop after one epoch."""
    if first_of_call and sps:
        return min(epoch_s, FIRST_EPOCH_MARGIN * epoch_steps / sps)
    return epoch_s


@dataclass
class _Run:
    """A call's run: its directory and state, its configs, the params it starts from and its PPO extension."""
    dir: Path
    state: dict
    ppo_cfg: config_dict.ConfigDict
    env_cfg: config_dict.ConfigDict
    params: object
    extension: object
    initial: bool = False    # params are still what the run starts from, before its extension's initial_params


def _resume_run(task: str, run_dir: Path, steps, overrides: Sequence[str]) -> _Run:
    _check_resume_overrides(overrides)
    state = checkpoints.load_run_state(run_dir)
    source = str(run_dir / checkpoints.RUN_STATE)
    if migration.run_task(state, source) != task:
        raise ValueError(f"--resume: {run_dir} is a {migration.run_task(state, source)!r} run, not {task!r}")
    ppo_cfg, env_cfg = migration.run_configs(state, source)
    apply_overrides({"ppo": ppo_cfg, "env": env_cfg}, overrides)
    state["task"], state["ppo_config"], state["env_config"] = task, ppo_cfg.to_dict(), env_cfg.to_dict()
    if steps is not None:
        state["target_steps"] = int(steps)  # extending a finished run is allowed
    started = state["env_steps"] > 0
    restored = checkpoints.load_checkpoint(run_dir) if started else extensions.load_init(state.get("init"))
    ext = extensions.extension(ppo_cfg, restored)
    return _Run(run_dir, state, ppo_cfg, env_cfg, restored, ext, initial=not started)


def _new_run(task: str, run_dir: Path, *, steps, overrides, preset, from_checkpoint, name, seed, recipe) -> _Run:
    if (run_dir / checkpoints.RUN_STATE).exists():
        raise FileExistsError(f"{run_dir} already holds a run: pass --resume to continue it or pick another --out")
    ppo_cfg, env_cfg = build_configs(task, preset, overrides)
    init = None
    if from_checkpoint:
        init = extensions.init_path(Path(from_checkpoint) if extensions.is_artifact(from_checkpoint)
                                    else checkpoints.resolve_checkpoint(from_checkpoint))
    restored = extensions.load_init(init)
    extensions.pin_campaign(ppo_cfg, init)
    state = {"task": task, "name": name or task, "preset": preset, "seed": seed,
             "ppo_config": ppo_cfg.to_dict(), "env_config": env_cfg.to_dict(), "init": init,
             "target_steps": int(steps if steps is not None else ppo_cfg.num_timesteps),
             "env_steps": 0, "minutes": 0.0, "calls": [], **({"recipe": recipe} if recipe else {})}
    run_dir.mkdir(parents=True, exist_ok=True)
    checkpoints.save_run_state(run_dir, state)
    return _Run(run_dir, state, ppo_cfg, env_cfg, restored, extensions.extension(ppo_cfg, restored), initial=True)


def _start(run: _Run, env) -> None:
    """A run that has not trained yet: its first params through its extension (which may read the task's
    observation sizes), and the run-state fields the extension keeps from them."""
    if not run.initial:
        return
    run.params = run.extension.initial_params(run.params, env)
    run.state.update(run.extension.state_fields(run.params))
    run.initial = False
    checkpoints.save_run_state(run.dir, run.state)


class _Epochs:
    """brax's progress and checkpoint hooks for one call: the metrics log and bar, a checkpoint and the run
    state after every epoch (a call killed mid-run still says what made it), and the --max-minutes stop."""

    def __init__(self, run: _Run, env, net_cfg, command: str, max_minutes, progress: bool, t_start: float):
        self.run, self.net_cfg, self.max_minutes, self.t_start = run, net_cfg, max_minutes, t_start
        self.offset = int(run.state["env_steps"])
        self.phase_offset = self.offset   # env steps before the running ppo.train call (which counts from 0)
        self.latest = {"params": run.params, "steps": self.offset}
        self.sps, self.epoch_end, self.last_total = [], time.monotonic(), self.offset
        self.minutes_before = float(run.state["minutes"])
        self.log = curves.MetricsLog(run.dir)
        self.bar = tqdm.tqdm(total=int(run.state["target_steps"]), initial=self.offset, unit="step",
                             unit_scale=True, disable=not progress, desc=run.state["name"], dynamic_ncols=True)
        self.call = {"date": checkpoints.utc_now(), "command": command, "from_steps": self.offset,
                     "to_steps": self.offset, "minutes": 0.0, "device": checkpoints.device_description(),
                     "backend": env.backend, "finished": False}
        run.state["calls"].append(self.call)

    def progress_fn(self, step, metrics):
        total = self.phase_offset + int(step)
        recorded = self.log.log(total, metrics)
        criterion = self.run.state.get("advance_at")
        if criterion and total > self.offset and recorded.get(criterion[0], -math.inf) >= criterion[1]:
            self.run.state["advanced"] = {"env_steps": total, criterion[0]: float(recorded[criterion[0]])}
            checkpoints.save_run_state(self.run.dir, self.run.state)
            raise _Advanced()
        self.sps += [recorded[k] for k in ("training/sps", "episode/sps") if k in recorded]   # per epoch / step
        self.bar.update(max(0, total - self.bar.n))
        sps = recorded.get("training/sps", recorded.get("episode/sps"))
        if sps is not None:
            self.bar.set_postfix(env_steps_per_s=f"{sps:,.0f}", refresh=False)

    def policy_params_fn(self, step, _make_policy, params):
        if step == 0:
            return
        now, state = time.monotonic(), self.run.state
        epoch_s, self.epoch_end = now - self.epoch_end, now
        total = self.phase_offset + int(step)
        checkpoints.save_checkpoint(self.run.dir, total, params, self.net_cfg, state.get("end_at"))
        self.latest.update(params=params, steps=total)
        state["env_steps"] = total
        self.call.update(to_steps=total, minutes=round((now - self.t_start) / 60.0, 2))
        state["minutes"] = self.minutes_before + (now - self.t_start) / 60.0
        checkpoints.save_run_state(self.run.dir, state)
        if state.get("end_at") is not None and total >= int(state["end_at"]):
            raise _Ended()
        next_s = next_epoch_estimate_s(epoch_s, total - self.last_total, self.sps[-1] if self.sps else None,
                                       first_of_call=self.last_total == self.offset)
        self.last_total = total
        if self.max_minutes is not None and now - self.t_start + next_s > 60.0 * self.max_minutes:
            raise _StopAtCheckpoint()

    def close(self, stopped: bool) -> float:
        """Record the call's end in the run state and curve; returns its steady env steps per second."""
        self.bar.close()
        minutes = (time.monotonic() - self.t_start) / 60.0
        steady = self.sps[1:]  # the first epoch includes jit compilation
        done_now = self.latest["steps"] - self.offset
        sps = sorted(steady)[len(steady) // 2] if steady else (done_now / (60 * minutes) if minutes else 0.0)
        state = self.run.state
        state["minutes"] = self.minutes_before + minutes
        self.call.update(to_steps=self.latest["steps"], minutes=round(minutes, 2), env_steps_per_s=round(sps, 1),
                         stopped_by_max_minutes=stopped, finished=True)
        state["env_steps_per_s"] = round(sps, 1)
        checkpoints.save_run_state(self.run.dir, state)
        self.log.close()
        curves.plot_curves(self.log.csv_path, self.run.dir / curves.PNG_NAME, title=f"{state['name']} (PPO)")
        return sps


def _run_ppo(run: _Run, env, epochs: _Epochs, num_steps: int, network_factory, seed: int) -> None:
    """One brax ppo.train call of num_steps from the newest params (the warm-up and PPO proper are one each)."""
    cfg, latest = run.ppo_cfg, epochs.latest
    epochs.phase_offset = latest["steps"]
    ppo.train(
        environment=env, num_timesteps=num_steps, num_envs=cfg.num_envs,
        episode_length=int(run.env_cfg.episode_length),
        wrap_env_fn=run.extension.wrap_env_fn(env, full_reset=bool(cfg.full_reset)),
        seed=seed + epochs.phase_offset,
        learning_rate=cfg.learning_rate, entropy_cost=cfg.entropy_cost, discounting=cfg.discounting,
        unroll_length=cfg.unroll_length, batch_size=cfg.batch_size, num_minibatches=cfg.num_minibatches,
        num_updates_per_batch=cfg.num_updates_per_batch, num_resets_per_eval=cfg.num_resets_per_eval,
        normalize_observations=cfg.normalize_observations, reward_scaling=cfg.reward_scaling,
        clipping_epsilon=cfg.clipping_epsilon, max_grad_norm=cfg.max_grad_norm,
        network_factory=network_factory, num_evals=_epochs(cfg, num_steps),
        run_evals=cfg.run_evals, num_eval_envs=cfg.num_eval_envs, deterministic_eval=cfg.deterministic_eval,
        log_training_metrics=cfg.log_training_metrics, training_metrics_steps=cfg.training_metrics_steps,
        progress_fn=epochs.progress_fn, policy_params_fn=epochs.policy_params_fn,
        randomization_fn=_randomization(cfg, env, seed + epochs.phase_offset),
        restore_params=None if latest["params"] is None else tuple(latest["params"]),
        restore_value_fn=latest["params"] is not None and latest["params"][2] is not None)


def _train_phases(run: _Run, env, epochs: _Epochs, seed: int) -> bool:
    """The critic-only warm-up, then PPO proper, inside the extension's loss term; True when --max-minutes
    stopped the call."""
    factory = ppo_networks.network_factory(run.ppo_cfg)
    epochs.net_cfg = brax_checkpoint.network_config(
        observation_size={k: tuple(v) for k, v in env.observation_size.items()},
        action_size=env.action_size, normalize_observations=run.ppo_cfg.normalize_observations,
        network_factory=factory)
    target = int(run.state["target_steps"])
    warmup_end = min(target, int(run.ppo_cfg.value_warmup_steps))
    try:
        with run.extension.loss_term(env, run.state):
            for end, network_factory in ((warmup_end, ppo_networks.frozen_policy_factory(factory)), (target, factory)):
                if end > epochs.latest["steps"]:
                    _run_ppo(run, env, epochs, end - epochs.latest["steps"], network_factory, seed)
    except _StopAtCheckpoint:
        return True
    except (_Advanced, _Ended):
        return False
    return False


def train(task: str, out, steps: int | None = None, num_envs: int | None = None, seed: int = 0,
          resume: bool = False, max_minutes: float | None = None, overrides: Sequence[str] = (),
          from_checkpoint=None, preset: str = "gpu", ship: bool = False,
          name: str | None = None, command: str = "", progress: bool = True,
          backend: str | None = None, recipe: dict | None = None,
          advance_at: tuple[str, float] | None = None, end_at: int | None = None) -> TrainResult:
    """One PPO run (or a call that resumes one). `recipe` ({"name", "stage", "sha256"}) is recorded in the run
    state and the artifact's provenance when a recipe runs it (training/recipes/runner.py). `advance_at`
    (metric, value): the run is complete at the first evaluation with the metric at or above the value (a
    backplay stage ends once success from its starts has risen). `end_at` (env steps): the run is complete at
    its first checkpoint at or after it (kept whatever follows), trained on the schedule of its target steps."""
    checkpoints.jax_setup()
    t_start = time.monotonic()
    run_dir = Path(out).resolve()  # orbax (GPU machine) refuses relative checkpoint paths
    if resume:
        run = _resume_run(task, run_dir, steps, overrides)
    else:
        run = _new_run(task, run_dir, steps=steps, overrides=overrides, preset=preset,
                       from_checkpoint=from_checkpoint, name=name, seed=seed, recipe=recipe)
    preset = run.state["preset"]  # a resumed toy run stays a toy run (and its artifact untrained)
    if advance_at is not None:
        run.state["advance_at"] = [str(advance_at[0]), float(advance_at[1])]
    if end_at is not None:
        run.state["end_at"] = int(end_at)
    if num_envs is not None:
        run.ppo_cfg.num_envs = run.state["ppo_config"]["num_envs"] = int(num_envs)
    _check_batch_shape(run.ppo_cfg)
    # the physics engine is this call's choice (a run may move between GPU and CPU sessions)
    run.env_cfg.backend = backend or default_backend()
    env = make_env(task, run.env_cfg)
    _start(run, env)
    epochs = _Epochs(run, env, None, command, max_minutes, progress, t_start)
    sps = epochs.close(_train_phases(run, env, epochs, seed))
    latest, target = epochs.latest, int(run.state["target_steps"])
    if latest["params"] is None:
        raise RuntimeError(f"{run_dir}: no parameters to export (zero steps trained and no --from)")
    artifact = export_run(run_dir, env, run.state, latest["params"], preset)
    ended = run.state.get("end_at") is not None and latest["steps"] >= int(run.state["end_at"])
    complete = latest["steps"] >= target or "advanced" in run.state or ended
    if ship and complete:
        export.ship_artifact(artifact, run.state)
    return TrainResult(run_dir, artifact, latest["steps"], target, run.state["minutes"], sps, complete=complete)


def export_run(run_dir: Path, env, state: dict, params, preset: str) -> Path:
    """The run's newest params → <run_dir>/<name>.safetensors, manifest from the env config."""
    steps = int(state["env_steps"])
    manifest = dict(env.manifest_fields())
    policy, rule = exported_policy(params[1], state["ppo_config"], state["env_config"])
    manifest.update(name=state["name"], activation=ACTIVATION, output_rule=rule,
                    trained=exported_as_trained(steps, preset),
                    provenance=run_provenance(state, steps, preset))
    path = run_dir / f"{state['name']}.safetensors"
    export_brax_ppo((params[0], policy), manifest, path,
                    observations_normalized=bool(state["ppo_config"]["normalize_observations"]))
    return path


def _env_fields_artifact(run_dir: Path, state: dict) -> Path:
    """An artifact with the run's env and network fields: its own newest export, or, mid-run (no export
    yet), the artifact it was started --from or the export of the run it was (same model, observation and
    network)."""
    own = run_dir / f"{state['name']}.safetensors"
    init = extensions.resolved(state["init"]) if state.get("init") else Path("")
    if not own.exists() and extensions.is_artifact(init):
        return init
    if own.exists() or init.parent.name != checkpoints.CHECKPOINT_DIR:
        return own
    parent = init.parent.parent
    try:
        return parent / f"{checkpoints.load_run_state(parent)['name']}.safetensors"
    except (OSError, ValueError, KeyError):
        return own     # named in the error below


def export_checkpoint(run_dir, env_steps, name: str, like=None) -> Path:
    """A run's kept checkpoint at `env_steps` → run_dir/<name>.safetensors: the env and network fields of
    `like` (default: the run's export, mid-run its --from run's), this run's provenance at that checkpoint's
    steps. A campaign screens its checkpoints and keeps the best one (e.g. the cheapest getup that still stands).
    Several env_steps: the mean of their policies' parameters (weight averaging along the run, which smooths the
    update-to-update noise of a policy whose success flips on small changes), the newest's normaliser."""
    run_dir = Path(run_dir)
    steps = sorted(int(n) for n in np.atleast_1d(env_steps))
    state = checkpoints.load_run_state(run_dir)
    ppo_cfg, env_cfg = migration.run_configs(state, str(run_dir / checkpoints.RUN_STATE))
    state = {**state, "ppo_config": ppo_cfg.to_dict(), "env_config": env_cfg.to_dict()}
    ckpts = [checkpoints.kept_checkpoint(run_dir, n, f"{n} env steps") for n in steps]
    like = Path(like) if like else _env_fields_artifact(run_dir, state)
    if not like.exists():
        raise FileNotFoundError(f"{like}: no export of the run (nor of a --from run) to take the manifest's "
                                "env fields from (name one with --like)")
    manifest = {k: v for k, v in read_artifact(like)[3].items() if k not in ("content_hash", "provenance")}
    sources = " + ".join(map(str, ckpts)) + (" (the mean of their policies)" if len(ckpts) > 1 else "")
    manifest["provenance"] = {**run_provenance(state, steps[-1], state["preset"]),
                              "exported_from": f"{sources} (env fields from {like})"}
    params = [checkpoints.load_checkpoint(c) for c in ckpts]
    mean = jax.tree.map(lambda *leaves: np.mean([np.asarray(x) for x in leaves], axis=0), *[p[1] for p in params])
    policy, rule = exported_policy(mean, ppo_cfg, env_cfg)
    manifest.update(name=name, output_rule=rule,
                    trained=exported_as_trained(steps[-1], state["preset"]))
    path = run_dir / f"{name}.safetensors"
    export_brax_ppo((params[-1][0], policy), manifest, path,
                    observations_normalized=bool(ppo_cfg.normalize_observations))
    return path
