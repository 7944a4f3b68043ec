"""Student distillation: brax `bc` online DAgger from the stitched teacher (training/distill/teacher.py).

Defaults are the seed's Table 5.2 and Algorithm 1: 1024 envs, demo length 6, β 1 → 0 as a step function
(the teacher's action is executed in the first DAgger phase only, `jp.where(step == 0, 1, 0)`), batch 256,
lr 4e-4, 4 epochs per phase, normalised observations, no tanh squash (raw actions), scramble time = the
episode length (1000), evaluation rollouts 1.15 × the episode length. The student sees the full term layout
(common/observation.py TERMS_UNION) so one network can walk and get up; the env is built with
obs_terms = TERMS_UNION, and the privileged waist height rides along in the observation dict for the
teacher only. The default env is `unified` (training/envs/unified.py: fallen / kneeling / standing starts,
joystick commands and pushes, falls not terminal), so the student sees both experts' situations and the
hand-overs between them, as the seed's student does; `task` picks another env (e.g. getup or joystick).

Export: brax bc's policy network is the PPO policy MLP with a NormalTanhDistribution head (2·23 outputs:
loc, scale). Without tanh squash (the seed's choice) brax acts with `loc` itself: exported as output rule
`linear` with the last layer cut to its first 23 rows (the `loc` half).
"""
from __future__ import annotations

import functools
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np
import tqdm
from brax.training.agents.bc import networks as bc_networks
from brax.training.agents.bc import train as bc
from ml_collections import config_dict
from mujoco_playground import wrapper

from common import events
from common import observation as obsdef
from common.artifact import read_artifact
from training import envs
from training.core import checkpoints, curves
from training.core.backend import default_backend
from training.core.networks import ACTIVATION
from training.core.overrides import TOY_ENV_OVERRIDES, apply_overrides
from training.distill.teacher import CHAIN, STUDENT_OBS_KEY, load_teacher, teacher_kind, teacher_observation
from training.export.brax import export_brax_ppo, ship_artifact

DEFAULT_TASK = "unified"  # the whole walk–fall–getup task (training/envs/unified.py); cli.py repeats it
# what the learner's teacher is (the chain's hand-over): a toy run keeps it (recipes/runner.py), as it keeps its
# sizes and rates at the toy preset's
LEARNER_KEYS = ("bc.handover_up_error",)
OUTPUT_RULE = "linear"   # the student acts with brax bc's loc, no tanh squash (Table 5.2)


def bc_config(preset: str = "gpu") -> config_dict.ConfigDict:
    cfg = config_dict.create(
        num_envs=1024, demo_length=6, batch_size=256, learning_rate=4e-4, epochs=4,
        normalize_observations=True, dagger_steps=1000,
        beta_teacher_phases=1,  # β = 1 for this many DAgger phases, then 0 (the seed's step function)
        beta_floor=0.0,  # β after the teacher's phases; > 0 keeps the teacher's states in every phase's data
        beta_decay_phases=0,  # phases over which β falls linearly from 1 to beta_floor (0: at once)
        num_evals=11,  # the initial evaluation + the seed's 10
        num_eval_envs=128, eval_length_factor=1.15,  # × the env's episode length (Table 5.2: 1150 of 1000)
        scramble_time=0,  # 0: the env's episode length (Table 5.2: 1000)
        reset=True, policy_hidden_layer_sizes=(512, 256, 128),
        # the chain teacher's rise → stand hand-over of labels: §4.8's gate (0.01); looser, a memoryless student
        # that cannot see the latch gets one label where the kneel is still (common/events.keyframe_stage)
        handover_up_error=events.KNEEL_GATE_UP_ERROR)
    if preset == "toy":
        cfg.update(dict(num_envs=8, demo_length=2, batch_size=8, dagger_steps=4, num_evals=0, num_eval_envs=4,
                        epochs=1, policy_hidden_layer_sizes=(16, 16)))
    elif preset != "gpu":
        raise ValueError(f"preset: {preset!r} is not one of ('gpu', 'toy')")
    return cfg


@dataclass
class DistillResult:
    run_dir: Path
    artifact: Path
    dagger_steps: int
    output_rule: str
    minutes: float


class _Stop(Exception):
    """--max-minutes: the run stops at its last checkpoint, unfinished."""


class _Ended(Exception):
    """end_at: the run ends, finished, at the checkpoint of that phase."""


STATE_FILE = "distill_state.json"   # a run's totals: phases and env steps, from which run it went on


def prior_progress(from_checkpoint) -> dict:
    """{"checkpoint": absolute path or None, "phases", "steps"}: where a --from run starts. The phases and
    steps of the checkpoint's run before it (its STATE_FILE's phases_before) plus the checkpoint's own."""
    if from_checkpoint is None:
        return {"checkpoint": None, "phases": 0, "steps": 0}
    ckpt = checkpoints.resolve_checkpoint(from_checkpoint).resolve()
    run = ckpt.parent.parent
    state_path = run / STATE_FILE
    if not state_path.exists():
        raise FileNotFoundError(f"{state_path}: the run of {ckpt} has no {STATE_FILE} (it says how many "
                                "phases and env steps came before); write one or start without --from")
    state = json.loads(state_path.read_text())
    per_phase = state.get("steps_per_phase")   # written when the run starts (older state files lack it)
    if per_phase is None:
        own_phases = int(state["phases"]) - int(state["phases_before"])
        if own_phases <= 0:
            raise ValueError(f"{state_path}: the run made no DAgger phase of its own")
        per_phase = (int(state["steps"]) - int(state["steps_before"])) // own_phases
    return {"checkpoint": str(ckpt), "phases": int(state["phases_before"]) + int(ckpt.name),
            "steps": int(state["steps_before"]) + int(ckpt.name) * per_phase}


def _write_state(run_dir: Path, before: dict, steps_per_phase: int, phases: int, steps: int, **fields) -> None:
    """STATE_FILE: the campaign's totals so far (`before` = prior_progress of the run it went on from)."""
    (run_dir / STATE_FILE).write_text(json.dumps(
        {"phases": phases, "steps": steps, "phases_before": before["phases"], "steps_before": before["steps"],
         "steps_per_phase": steps_per_phase, "from": before["checkpoint"], **fields}, indent=1) + "\n")


def beta_schedule(teacher_phases: int, floor: float = 0.0, decay_phases: int = 0):
    """β(step) = probability that the teacher's action is executed at a step: 1 in the first `teacher_phases`
    DAgger phases, then falling linearly to `floor` over `decay_phases` (the seed's Algorithm 1: teacher_phases
    1, floor 0, no decay). Brax's bc learns from the newest phase only: a floor keeps the states the teacher
    reaches (standing, the kneel) in every phase, where a student that falls early would otherwise forget them."""
    if not 0.0 <= floor <= 1.0:
        raise ValueError(f"beta_floor: {floor} is not a probability in [0, 1]")
    if decay_phases < 0:
        raise ValueError(f"beta_decay_phases: {decay_phases} is negative")

    def beta(step):
        fall = jnp.clip((step - teacher_phases + 1) / max(decay_phases, 1), 0.0, 1.0)
        return jnp.where(step < teacher_phases, 1.0, 1.0 - (1.0 - floor) * fall)
    return beta


def loc_half(policy_params) -> dict:
    """brax bc's policy params with the last layer cut to its first 23 rows: the tanh-normal head's `loc`,
    the action itself when there is no tanh squash (output rule `linear`)."""
    inner = dict(policy_params["params"])
    last = f"hidden_{len(inner) - 1}"
    inner[last] = {"kernel": np.asarray(inner[last]["kernel"])[:, :obsdef.NUM_JOINTS],
                   "bias": np.asarray(inner[last]["bias"])[:obsdef.NUM_JOINTS]}
    return {"params": inner}


def export_student(params, env, path, name: str, trained: bool, provenance: dict) -> str:
    """brax bc (normalizer, policy) → artifact (act = loc: output rule `linear`); returns the output rule."""
    manifest = dict(env.manifest_fields())
    manifest.update(name=name, activation=ACTIVATION, output_rule=OUTPUT_RULE, trained=trained,
                    provenance=provenance)
    export_brax_ppo((params[0], loc_half(params[1])), manifest, path)
    return OUTPUT_RULE


def dagger_configs(task: str, preset: str, overrides: Sequence[str], num_envs: int | None, union_terms: bool = True):
    """(bc config, env config) of a DAgger run: the env with the student's full term layout (union_terms; else
    the task's own: the chain's student is a getup policy), the toy preset's env sizes, --config applied; the
    batch shape checked."""
    cfg, env_cfg = bc_config(preset), envs.default_config(task)
    if union_terms:
        env_cfg.obs_terms = [list(t) for t in obsdef.TERMS_UNION]
    if preset == "toy":
        env_cfg.update({k: v for k, v in TOY_ENV_OVERRIDES.items() if k in env_cfg})
    apply_overrides({"bc": cfg, "env": env_cfg}, overrides)
    if num_envs is not None:
        cfg.num_envs = int(num_envs)
    if (cfg.num_envs * cfg.demo_length) % cfg.batch_size:
        raise ValueError(f"num_envs·demo_length = {cfg.num_envs}·{cfg.demo_length} must be a multiple of "
                         f"batch_size {cfg.batch_size}")
    evals_after_init = max(cfg.num_evals - 1, 1)
    if cfg.dagger_steps % evals_after_init:
        raise ValueError(f"dagger_steps {cfg.dagger_steps} must be a multiple of num_evals − 1 = {evals_after_init}")
    return cfg, env_cfg


def _newest_params(run_dir: Path, params):
    """(params as numpy, phases done): bc.train's, or after a stop the newest checkpoint's."""
    done = checkpoints.list_checkpoints(run_dir)
    if params is None:
        if not done:
            raise RuntimeError(f"{run_dir}: stopped before the first checkpoint; nothing to export")
        params = checkpoints.load_checkpoint(done[-1])
    return jax.tree.map(np.asarray, tuple(params)), int(done[-1].name) if done else 0


def _dagger_env(task: str, env_cfg, teacher: dict, handover_up_error: float):
    """(env, the env brax bc trains in: Playground's wrapper with what the teacher switches on in the observation:
    the waist height, or the chain's stage)."""
    env = envs.make(task, config=env_cfg)
    wrapped = wrapper.wrap_for_brax_training(env, episode_length=int(env_cfg.episode_length), full_reset=True)
    return env, teacher_observation(teacher, handover_up_error)(wrapped, env)


def _provenance(before: dict, phases: int, phase_env_steps: int, minutes: float, command: str) -> dict:
    """The artifact's provenance of a call that made `phases` DAgger phases after `before` (prior_progress)."""
    return {"git_commit": checkpoints.git_commit(), "steps": before["steps"] + int(phases * phase_env_steps),
            "date": checkpoints.utc_now(), "command": command or "unknown",
            "device": checkpoints.device_description(), "minutes": round(minutes, 2),
            # this call's env steps per wall second (evaluations and compilation included)
            "env_steps_per_s": round(phases * phase_env_steps / max(60.0 * minutes, 1e-9), 1),
            "algorithm": "brax bc (online DAgger)", "dagger_phases": before["phases"] + phases,
            "dagger_phases_before": before["phases"], "from": before["checkpoint"]}


def distill(teacher: dict, out, task: str = DEFAULT_TASK, overrides: Sequence[str] = (),
            preset: str = "gpu", seed: int = 0, num_envs: int | None = None, ship: bool = False,
            command: str = "", progress: bool = True, max_minutes: float | None = None,
            name: str = "student", backend: str | None = None, from_checkpoint=None,
            recipe: dict | None = None, end_at: int | None = None) -> DistillResult:
    """One DAgger run from `teacher` ({role: artifact}: getup + joystick, the stitched teacher; roll + rise +
    stand, the keyframe getup's chain); with `from_checkpoint` (a checkpoint or a distill run directory → its
    newest) the student starts from those params and normaliser (brax bc restore_checkpoint_path; the optimiser restarts
    and, as in any bc run, the teacher acts in the first phase), and the phase count, curve and provenance
    continue from that run's (STATE_FILE), so a campaign goes on across sessions. With `end_at` (a phase of this
    run with a checkpoint: a multiple of dagger_steps / (num_evals − 1)) the run ends there, finished, on the
    schedule of its dagger_steps (β, evaluation resets): a campaign's best phase as its end."""

    checkpoints.jax_setup()
    t_start = time.monotonic()
    run_dir = Path(out).resolve()  # orbax (GPU machine) refuses relative checkpoint paths
    if checkpoints.list_checkpoints(run_dir):
        raise FileExistsError(f"{run_dir}: already holds DAgger checkpoints; give a new --out "
                              f"(continue a run with --from {run_dir})")
    before = prior_progress(from_checkpoint)
    run_dir.mkdir(parents=True, exist_ok=True)
    cfg, env_cfg = dagger_configs(task, preset, overrides, num_envs, union_terms=teacher_kind(teacher) != CHAIN)

    check_end_at(end_at, cfg)
    env_cfg.backend = backend or default_backend()
    env, wrapped = _dagger_env(task, env_cfg, teacher, float(cfg.handover_up_error))
    teacher_fn = load_teacher(teacher, env.obs_terms, env.manifest_fields()["action_scale"])
    episode_length = int(env_cfg.episode_length)
    factory = functools.partial(bc_networks.make_bc_networks,
                                policy_hidden_layer_sizes=tuple(cfg.policy_hidden_layer_sizes),
                                policy_obs_key=STUDENT_OBS_KEY)
    log = curves.MetricsLog(run_dir)
    bar = tqdm.tqdm(total=cfg.dagger_steps, unit="phase", desc=name, disable=not progress, dynamic_ncols=True)
    phase_env_steps = cfg.num_envs * cfg.demo_length

    def progress_fn(step, metrics):
        step = int(step)
        recorded = log.log(before["steps"] + step * phase_env_steps,
                           {k: np.mean(np.asarray(v)) for k, v in metrics.items()})
        bar.update(max(0, step - bar.n))
        if "SPS" in recorded:
            bar.set_postfix(samples_per_s=f"{recorded['SPS']:,.0f}", refresh=False)
        if end_at is not None and step >= end_at:
            raise _Ended()
        if max_minutes is not None and step > 0 and time.monotonic() - t_start > 60.0 * max_minutes:
            raise _Stop()

    # written now, so that a run killed mid-call (a session cut off) can still be continued with --from
    _write_state(run_dir, before, phase_env_steps, before["phases"], before["steps"], artifact=f"{name}.safetensors",
                 command=command or "unknown", date=checkpoints.utc_now(), finished=False)
    params, stopped = _train_bc(cfg, wrapped, teacher_fn, factory, progress_fn, seed, episode_length,
                                (run_dir / checkpoints.CHECKPOINT_DIR).resolve(), before["checkpoint"])
    bar.close()
    log.close()
    curves.plot_curves(log.csv_path, run_dir / curves.PNG_NAME, title=f"{name} (DAgger)")
    params, phases = _newest_params(run_dir, params)
    minutes = (time.monotonic() - t_start) / 60.0
    provenance = {**_provenance(before, phases, phase_env_steps, minutes, command), "preset": preset,
                  "backend": env_cfg.backend, "teacher": {k: str(v) for k, v in teacher.items()},
                  "stopped_by_max_minutes": stopped, **({"recipe": recipe} if recipe else {})}
    artifact = run_dir / f"{name}.safetensors"
    trained = provenance["dagger_phases"] > 0 and preset != "toy"
    _write_state(run_dir, before, phase_env_steps, provenance["dagger_phases"], provenance["steps"],
                 artifact=artifact.name, command=provenance["command"], date=provenance["date"],
                 minutes=provenance["minutes"], stopped_by_max_minutes=stopped, finished=True,
                 **({"end_at": int(end_at)} if end_at is not None else {}))
    rule = export_student(params, env, artifact, name, trained, provenance)
    if ship and not stopped:
        ship_artifact(artifact, {"task": f"distill ({task} env)"})
    return DistillResult(run_dir, artifact, phases, rule, minutes)


def _train_bc(cfg, env, teacher, network_factory, progress_fn, seed: int, episode_length: int, ckpt_root: Path,
              restore) -> tuple[object, bool]:
    """brax bc's DAgger loop with the run's settings, checkpointing under `ckpt_root`, from `restore` (a
    checkpoint or None); (its params, or None when --max-minutes stopped it, and whether it was stopped)."""
    try:
        _, params, _ = bc.train(
            demo_length=cfg.demo_length, teacher_inference_fn=teacher,
            normalize_observations=cfg.normalize_observations, epochs=cfg.epochs, tanh_squash=False,
            env=env, num_envs=cfg.num_envs, num_eval_envs=cfg.num_eval_envs,
            eval_length=round(cfg.eval_length_factor * episode_length), batch_size=cfg.batch_size,
            scramble_time=cfg.scramble_time or episode_length, network_factory=network_factory,
            progress_fn=progress_fn, seed=seed, learning_rate=cfg.learning_rate, dagger_steps=cfg.dagger_steps,
            dagger_beta_fn=beta_schedule(cfg.beta_teacher_phases, cfg.beta_floor, cfg.beta_decay_phases),
            num_evals=cfg.num_evals,
            reset=cfg.reset, save_checkpoint_path=str(ckpt_root), restore_checkpoint_path=restore)
    except _Stop:
        return None, True
    except _Ended:
        return None, False
    return params, False


def check_end_at(end_at: int | None, cfg) -> None:
    """end_at must name a phase the run checkpoints (distill's docstring)."""
    if end_at is None:
        return
    every = cfg.dagger_steps // max(cfg.num_evals - 1, 1)
    if not 0 < int(end_at) <= cfg.dagger_steps or int(end_at) % every:
        raise ValueError(f"distill: end_at {end_at} is not a checkpointed phase of this run (a multiple of "
                         f"{every} up to bc.dagger_steps {cfg.dagger_steps})")


def export_phase(run_dir, phase: int, name: str, like=None) -> Path:
    """Export a finished run's checkpoint at DAgger phase `phase` as run_dir/<name>.safetensors, with the
    manifest of the run's final artifact `like` (default: the one its STATE_FILE names; same env and
    network) and that phase's steps: e.g. the
    seed's DAgger-400 / DAgger-1000 students of Fig. 5.1 as checkpoints of one longer run. (Not the same as
    a run of that length: brax bc resets the envs at each evaluation, every dagger_steps / (num_evals − 1)
    phases, so a shorter run resets more often.)"""
    run_dir = Path(run_dir)
    ckpt = checkpoints.kept_checkpoint(run_dir, phase, f"phase {phase}")
    at = prior_progress(ckpt)    # the campaign's phases and env steps at this checkpoint
    if like is None:
        like = run_dir / json.loads((run_dir / STATE_FILE).read_text())["artifact"]
    _, _, _, manifest = read_artifact(like)
    prov = dict(manifest["provenance"])
    if "dagger_phases" not in prov:
        raise ValueError(f"{like}: its provenance has no dagger_phases; not a distilled student")
    prov.update(steps=at["steps"], dagger_phases=at["phases"],
                exported_from=f"{ckpt} (checkpoint of the run that made {Path(like).name})")
    params = checkpoints.load_checkpoint(ckpt)
    policy = loc_half(params[1]) if manifest["output_rule"] == "linear" else params[1]
    fields = {k: v for k, v in manifest.items() if k != "content_hash"}
    fields.update(name=name, provenance=prov, trained=bool(manifest["trained"]) and at["phases"] > 0)
    path = run_dir / f"{name}.safetensors"
    export_brax_ppo((params[0], policy), fields, path)
    return path
