"""PPO training runs (brax ppo.train on the MJX envs of training/envs), resumable and time-boxed.

    python -m training train joystick --steps 200_000_000 --out runs/joystick --max-minutes 9 [--resume]
(a policy that ships comes from a recipe: `python -m training recipe NAME`, training/recipe_runner.py)

One call trains until the target env-step count or until --max-minutes would be overrun by the next
epoch, checkpointing after every epoch (brax's `policy_params_fn` hook: params arrive on the host there,
between two jitted epochs, so stopping there is clean). Every call exports the newest policy to
<out>/<name>.safetensors; --ship also copies it to policies/<name>/ and appends a row to its CARD.md.
"""
from __future__ import annotations

import math
import shutil
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ml_collections import config_dict

from common.artifact import read_artifact
from training import checkpoints, curves, migration, ppo_networks, student_finetune
from training.configs import build_configs
from training.export import export_brax_ppo, exported_as_trained, exported_policy, run_provenance
from training.checkpoints import REPO_ROOT
from training.overrides import apply_overrides
from training.ppo_networks import ACTIVATION

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


def _randomization(cfg, env=None, seed: int = 0):
    """brax's randomization_fn, or None. On the CPU backend the env randomises its C simulations itself
    (the same function, applied on the host) and brax gets None."""
    if env is not None and getattr(env, "backend", "mjx") == "cpu":
        if cfg.domain_randomization:
            from training import envs
            env.randomize_on_host(envs.domain_randomize, seed)
        return None
    if not cfg.domain_randomization:
        return None
    from training import envs
    return envs.domain_randomize


def default_backend() -> str:
    """mjx where JAX sees a GPU, else the CPU backend (MuJoCo C on all cores)."""
    import jax
    return "mjx" if any(d.platform == "gpu" for d in jax.devices()) else "cpu"


def make_env(task: str, env_cfg: config_dict.ConfigDict):
    from training import envs
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


def run_name(task: str, env_cfg) -> str:
    return f"{task}_{env_cfg.stage}" if task.startswith("getup") and "stage" in env_cfg else task


def train(task: str, out, steps: int | None = None, num_envs: int | None = None, seed: int = 0,
          resume: bool = False, max_minutes: float | None = None, overrides: Sequence[str] = (),
          stage: str | None = None, from_checkpoint=None, preset: str = "gpu", ship: bool = False,
          name: str | None = None, command: str = "", progress: bool = True,
          backend: str | None = None, recipe: dict | None = None) -> TrainResult:
    """One PPO run (or a call that resumes one). `recipe` ({"name", "stage", "sha256"}) is recorded in the run
    state and the artifact's provenance when a recipe runs it (training/recipe_runner.py)."""
    from brax.training.agents.ppo import train as ppo
    import tqdm

    checkpoints.jax_setup()
    t_start = time.monotonic()
    run_dir = Path(out).resolve()  # orbax (GPU machine) refuses relative checkpoint paths
    if resume:
        _check_resume_overrides(overrides)
        state = checkpoints.load_run_state(run_dir)
        if state["task"] != task:
            raise ValueError(f"--resume: {run_dir} is a {state['task']!r} run, not {task!r}")
        preset = state["preset"]  # a toy run stays a toy run (and its artifact untrained)
        ppo_cfg, env_cfg = migration.run_configs(state, str(run_dir / checkpoints.RUN_STATE))
        apply_overrides({"ppo": ppo_cfg, "env": env_cfg}, overrides)
        state["ppo_config"], state["env_config"] = ppo_cfg.to_dict(), env_cfg.to_dict()
        if steps is not None:
            state["target_steps"] = int(steps)  # extending a finished run is allowed
        restore = checkpoints.load_checkpoint(run_dir) if state["env_steps"] > 0 else state.get("init")
        if isinstance(restore, str):
            restore = student_finetune.init_params(checkpoints.load_checkpoint(restore), ppo_cfg)
    else:
        if (run_dir / checkpoints.RUN_STATE).exists():
            raise FileExistsError(f"{run_dir} already holds a run: pass --resume to continue it or pick "
                                  "another --out")
        ppo_cfg, env_cfg = build_configs(task, preset, stage, overrides)
        init = str(checkpoints.resolve_checkpoint(from_checkpoint)) if from_checkpoint else None
        restore = student_finetune.init_params(checkpoints.load_checkpoint(init) if init else None, ppo_cfg)
        state = {"task": task, "name": name or run_name(task, env_cfg), "preset": preset, "seed": seed,
                 "ppo_config": ppo_cfg.to_dict(), "env_config": env_cfg.to_dict(), "init": init,
                 "target_steps": int(steps if steps is not None else ppo_cfg.num_timesteps),
                 "env_steps": 0, "minutes": 0.0, "calls": [], **({"recipe": recipe} if recipe else {}),
                 # where the BC term's decay counts from (student_finetune.py)
                 "bc_count_start": float(student_finetune.sample_count(restore[0])) if restore else 0.0}
        run_dir.mkdir(parents=True, exist_ok=True)
        checkpoints.save_run_state(run_dir, state)
    if num_envs is not None:
        ppo_cfg.num_envs = state["ppo_config"]["num_envs"] = int(num_envs)
    _check_batch_shape(ppo_cfg)
    # the physics engine is this call's choice (a run may move between GPU and CPU sessions)
    env_cfg.backend = backend or default_backend()

    env = make_env(task, env_cfg)
    offset, target = int(state["env_steps"]), int(state["target_steps"])
    factory = ppo_networks.network_factory(ppo_cfg)
    from brax.training import checkpoint as brax_checkpoint
    net_cfg = brax_checkpoint.network_config(
        observation_size={k: tuple(v) for k, v in env.observation_size.items()},
        action_size=env.action_size, normalize_observations=ppo_cfg.normalize_observations,
        network_factory=factory)

    log = curves.MetricsLog(run_dir)
    bar = tqdm.tqdm(total=target, initial=offset, unit="step", unit_scale=True, disable=not progress,
                    desc=state["name"], dynamic_ncols=True)
    clock = {"last_epoch_end": time.monotonic(), "epoch_s": 0.0, "sps": [], "last_total": offset}
    latest = {"params": restore, "steps": offset}
    phase = {"offset": offset}   # env steps before the running ppo.train call (which counts from 0)
    # this call's record is written with every checkpoint, so a run killed mid-call still says what made it
    minutes_before = float(state["minutes"])
    call = {"date": checkpoints.utc_now(), "command": command, "from_steps": offset, "to_steps": offset,
            "minutes": 0.0, "device": checkpoints.device_description(), "backend": env_cfg.backend,
            "finished": False}
    state["calls"].append(call)

    def progress_fn(step, metrics):
        total = phase["offset"] + int(step)
        recorded = log.log(total, metrics)
        for key in ("training/sps", "episode/sps"):  # per epoch / per training step
            if key in recorded:
                clock["sps"].append(recorded[key])
        bar.update(max(0, total - bar.n))
        sps = recorded.get("training/sps", recorded.get("episode/sps"))
        if sps is not None:
            bar.set_postfix(env_steps_per_s=f"{sps:,.0f}", refresh=False)

    def policy_params_fn(step, _make_policy, params):
        if step == 0:
            return
        now = time.monotonic()
        clock["epoch_s"], clock["last_epoch_end"] = now - clock["last_epoch_end"], now
        total = phase["offset"] + int(step)
        checkpoints.save_checkpoint(run_dir, total, params, net_cfg)
        latest.update(params=params, steps=total)
        state["env_steps"] = total
        call.update(to_steps=total, minutes=round((now - t_start) / 60.0, 2))
        state["minutes"] = minutes_before + (now - t_start) / 60.0
        checkpoints.save_run_state(run_dir, state)
        epoch_steps = total - clock["last_total"]
        next_s = next_epoch_estimate_s(clock["epoch_s"], epoch_steps, clock["sps"][-1] if clock["sps"] else None,
                                       first_of_call=clock["last_total"] == offset)
        clock["last_total"] = total
        if max_minutes is not None and now - t_start + next_s > 60.0 * max_minutes:
            raise _StopAtCheckpoint()

    def run_ppo(num_steps: int, network_factory):
        phase["offset"] = latest["steps"]
        ppo.train(
            environment=env, num_timesteps=num_steps, num_envs=ppo_cfg.num_envs,
            episode_length=int(env_cfg.episode_length),
            wrap_env_fn=student_finetune.wrap_env_fn(ppo_cfg, env, full_reset=bool(ppo_cfg.full_reset)),
            seed=seed + phase["offset"],
            learning_rate=ppo_cfg.learning_rate, entropy_cost=ppo_cfg.entropy_cost,
            discounting=ppo_cfg.discounting, unroll_length=ppo_cfg.unroll_length,
            batch_size=ppo_cfg.batch_size, num_minibatches=ppo_cfg.num_minibatches,
            num_updates_per_batch=ppo_cfg.num_updates_per_batch,
            num_resets_per_eval=ppo_cfg.num_resets_per_eval,
            normalize_observations=ppo_cfg.normalize_observations, reward_scaling=ppo_cfg.reward_scaling,
            clipping_epsilon=ppo_cfg.clipping_epsilon, max_grad_norm=ppo_cfg.max_grad_norm,
            network_factory=network_factory, num_evals=_epochs(ppo_cfg, num_steps),
            run_evals=ppo_cfg.run_evals, num_eval_envs=ppo_cfg.num_eval_envs,
            deterministic_eval=ppo_cfg.deterministic_eval,
            log_training_metrics=ppo_cfg.log_training_metrics,
            training_metrics_steps=ppo_cfg.training_metrics_steps,
            progress_fn=progress_fn, policy_params_fn=policy_params_fn,
            randomization_fn=_randomization(ppo_cfg, env, seed + phase["offset"]),
            restore_params=None if latest["params"] is None else tuple(latest["params"]),
            restore_value_fn=latest["params"] is not None and latest["params"][2] is not None)

    # (end step, networks): the critic-only warm-up, then PPO proper
    warmup_end = min(target, int(ppo_cfg.value_warmup_steps))
    phases = ((warmup_end, ppo_networks.frozen_policy_factory(factory)), (target, factory))
    stopped = False
    try:
        with student_finetune.teacher_term(ppo_cfg, env, float(state.get("bc_count_start", 0.0))):
            for end, network_factory in phases:
                if end > latest["steps"]:
                    run_ppo(end - latest["steps"], network_factory)
    except _StopAtCheckpoint:
        stopped = True
    bar.close()
    minutes = (time.monotonic() - t_start) / 60.0
    steady = clock["sps"][1:]  # the first epoch includes jit compilation
    done_now = latest["steps"] - offset
    sps = sorted(steady)[len(steady) // 2] if steady else (done_now / (60 * minutes) if minutes else 0.0)
    state["minutes"] = minutes_before + minutes
    call.update(to_steps=latest["steps"], minutes=round(minutes, 2), env_steps_per_s=round(sps, 1),
                stopped_by_max_minutes=stopped, finished=True)
    state["env_steps_per_s"] = round(sps, 1)
    checkpoints.save_run_state(run_dir, state)
    log.close()
    curves.plot_curves(log.csv_path, run_dir / curves.PNG_NAME, title=f"{state['name']} (PPO)")

    if latest["params"] is None:
        raise RuntimeError(f"{run_dir}: no parameters to export (zero steps trained and no --from)")
    artifact = export_run(run_dir, env, state, latest["params"], preset)
    if ship and latest["steps"] >= target:
        ship_artifact(artifact, state)
    return TrainResult(run_dir, artifact, latest["steps"], target, state["minutes"], sps,
                       complete=latest["steps"] >= target)


def export_run(run_dir: Path, env, state: dict, params, preset: str) -> Path:
    """The run's newest params → <run_dir>/<name>.safetensors, manifest from the env config."""
    steps = int(state["env_steps"])
    manifest = dict(env.manifest_fields())
    policy, rule = exported_policy(params[1], state["ppo_config"])
    manifest.update(name=state["name"], activation=ACTIVATION, output_rule=rule,
                    trained=exported_as_trained(steps, preset, state["env_config"]),
                    provenance=run_provenance(state, steps, preset))
    path = run_dir / f"{state['name']}.safetensors"
    export_brax_ppo((params[0], policy), manifest, path,
                    observations_normalized=bool(state["ppo_config"]["normalize_observations"]))
    return path


def _env_fields_artifact(run_dir: Path, state: dict) -> Path:
    """An artifact with the run's env and network fields: its own newest export, or, mid-run (no export
    yet), the export of the run it was started --from (same model, observation and network)."""
    own = run_dir / f"{state['name']}.safetensors"
    init = Path(state.get("init") or "")
    if own.exists() or init.parent.name != checkpoints.CHECKPOINT_DIR:
        return own
    parent = init.parent.parent
    try:
        return parent / f"{checkpoints.load_run_state(parent)['name']}.safetensors"
    except (OSError, ValueError, KeyError):
        return own     # named in the error below


def export_checkpoint(run_dir, env_steps: int, name: str, like=None) -> Path:
    """A run's kept checkpoint at `env_steps` → run_dir/<name>.safetensors: the env and network fields of
    `like` (default: the run's export, mid-run its --from run's), this run's provenance at that checkpoint's
    steps. A campaign screens its checkpoints and keeps the best one (e.g. the cheapest getup that still stands)."""
    run_dir = Path(run_dir)
    state = checkpoints.load_run_state(run_dir)
    ppo_cfg, env_cfg = migration.run_configs(state, str(run_dir / checkpoints.RUN_STATE))
    state = {**state, "ppo_config": ppo_cfg.to_dict(), "env_config": env_cfg.to_dict()}
    ckpt = checkpoints.kept_checkpoint(run_dir, env_steps, f"{env_steps} env steps")
    like = Path(like) if like else _env_fields_artifact(run_dir, state)
    if not like.exists():
        raise FileNotFoundError(f"{like}: no export of the run (nor of a --from run) to take the manifest's "
                                "env fields from (name one with --like)")
    manifest = {k: v for k, v in read_artifact(like)[3].items() if k not in ("content_hash", "provenance")}
    manifest["provenance"] = {**run_provenance(state, env_steps, state["preset"]),
                              "exported_from": f"{ckpt} (env fields from {like})"}
    params = checkpoints.load_checkpoint(ckpt)
    policy, rule = exported_policy(params[1], ppo_cfg)
    manifest.update(name=name, output_rule=rule,
                    trained=exported_as_trained(int(env_steps), state["preset"], env_cfg))
    path = run_dir / f"{name}.safetensors"
    export_brax_ppo((params[0], policy), manifest, path,
                    observations_normalized=bool(ppo_cfg.normalize_observations))
    return path


def ship_artifact(artifact: Path, state: dict, policies_root=checkpoints.POLICIES_ROOT) -> Path:
    """Copy the artifact to policies/<name>/<name>.safetensors and append its provenance row to that folder's
    CARD.md (created from the card template for a new policy)."""
    manifest = read_artifact(artifact)[3]
    prov = manifest["provenance"]
    folder = checkpoints.policy_dir(manifest["name"], policies_root)
    folder.mkdir(parents=True, exist_ok=True)
    shipped = folder / f"{manifest['name']}.safetensors"
    if shipped.resolve() != Path(artifact).resolve():
        shutil.copyfile(artifact, shipped)
    task = state["task"] + ("" if manifest["trained"] else " (SMOKE TEST, NOT TRAINED)")
    try:
        shown = shipped.resolve().relative_to(REPO_ROOT)
    except ValueError:
        shown = shipped
    recipe = prov.get("recipe")
    checkpoints.append_provenance_row({
        "date": prov["date"], "artifact": f"`{shown}`", "name": manifest["name"], "task": task,
        "trained": "yes" if manifest["trained"] else "no", "env steps": prov["steps"],
        "minutes": prov.get("minutes", ""), "env-steps/s": prov.get("env_steps_per_s", ""),
        "device": prov.get("device", ""), "git commit": prov["git_commit"],
        "content hash": manifest["content_hash"][:12],
        "command": f"`{prov['command']}`" + (f" (recipe {recipe['name']} {recipe['sha256'][:12]})" if recipe else ""),
        "evaluation": ""}, folder / checkpoints.CARD)
    return shipped
