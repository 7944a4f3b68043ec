"""Export policies to runtime artifacts (policies/ARTIFACT.md): brax PPO params → artifact (the manifest's
defaults and the golden vectors: common/golden.py)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from common.artifact import read_artifact, write_artifact
from common.golden import base_manifest
from training import checkpoints


# ---------------------------------------------------------------- brax PPO
def brax_policy_layers(policy_params: Mapping[str, Any]) -> list[tuple[np.ndarray, np.ndarray]]:
    """brax MLP params {'params': {'hidden_i': {'kernel' (in, out), 'bias'}}} → [(W (out, in), b)]."""
    inner = policy_params.get("params", policy_params)
    names = sorted(inner, key=lambda n: int(n.split("_")[-1]) if n.startswith("hidden_") else -1)
    if not names or any(not n.startswith("hidden_") for n in names):
        raise ValueError(f"policy_params: expected only brax MLP layers hidden_0..hidden_N, got {sorted(inner)} "
                         "(layer norm / separate-std policies are not supported by schema 1)")
    if [int(n.split("_")[-1]) for n in names] != list(range(len(names))):
        raise ValueError(f"policy_params: layer names are not contiguous: {names}")
    layers = []
    for n in names:
        if set(inner[n]) != {"kernel", "bias"}:
            raise ValueError(f"policy_params: {n} must hold exactly kernel and bias, has {sorted(inner[n])}")
        kernel = np.asarray(inner[n]["kernel"], dtype=np.float32)
        layers.append((np.ascontiguousarray(kernel.T), np.asarray(inner[n]["bias"], dtype=np.float32)))
    return layers


NORMAL = "normal"   # ppo.policy_distribution of a fine-tuned student (training/student_finetune.py)


def student_layers(policy) -> dict:
    """The "normal" PPO policy's params → brax MLP layers hidden_0..hidden_N (its mean: the exported student,
    output rule `linear`; the std is training's only)."""
    inner = policy["params"]
    mlp = inner["MLP_0"]
    layers = {f"hidden_{i}": mlp[f"hidden_{i}"] for i in range(len(mlp))}
    layers[f"hidden_{len(mlp)}"] = inner["Dense_0"]
    return {"params": layers}


def exported_policy(policy, ppo_config) -> tuple[dict, str]:
    """(policy params as the artifact's MLP, output rule) of a PPO run's policy: a fine-tuned student acts with
    its mean (`linear`), any other PPO policy is brax's tanh-normal."""
    if ppo_config.get("policy_distribution") == NORMAL:
        return student_layers(policy), "linear"
    return policy, "tanh_normal"


def export_brax_ppo(params, manifest_fields: Mapping[str, Any], path, observations_normalized: bool = True,
                    obs_key: str = "state") -> str:
    """(normalizer_params, policy_params, value_params) from brax.training.agents.ppo → artifact at `path`.

    manifest_fields: any base_manifest() field (activation must match the brax network's; brax's PPO
    default is swish). observations_normalized=False (PPO trained with normalize_observations=False)
    stores mean 0, std 1. Returns the content hash.
    """
    normalizer_params, policy_params = params[0], params[1]
    layers = brax_policy_layers(policy_params)
    obs_size = layers[0][0].shape[1]
    if observations_normalized:
        mean, std = normalizer_params.mean, normalizer_params.std
        if isinstance(mean, Mapping):  # dict observations: the policy reads obs[obs_key]
            mean, std = mean[obs_key], std[obs_key]
        mean, std = np.asarray(mean, np.float32), np.asarray(std, np.float32)
    else:
        mean, std = np.zeros(obs_size, np.float32), np.ones(obs_size, np.float32)
    manifest = base_manifest(**dict(manifest_fields))
    return write_artifact(path, layers, mean, std, manifest)


# ---------------------------------------------------------------- golden random policy and vectors
def run_provenance(state: dict, steps: int, preset: str) -> dict:
    """The manifest's provenance of a run's params at `steps`: its calls so far (a run still going has its
    current call recorded at every checkpoint). A fine-tune toward a stitched teacher names it, as a distilled
    student does (`common.artifact.stitched_teacher`: the demo and Fig. 5.1 follow a student with it)."""
    last = state["calls"][-1] if state["calls"] else {}
    teacher = state.get("ppo_config", {}).get("teacher") or {}
    return {"git_commit": checkpoints.git_commit(), "steps": int(steps), "date": checkpoints.utc_now(),
            "command": " ; ".join(c["command"] for c in state["calls"] if c["command"]) or "unknown",
            "device": last.get("device", "unknown"), "minutes": round(float(state["minutes"]), 2),
            "env_steps_per_s": state.get("env_steps_per_s", 0.0), "algorithm": "brax ppo",
            "preset": preset, "init": state.get("init") or "",
            **({"recipe": state["recipe"]} if state.get("recipe") else {}),
            **({"teacher": {k: teacher[k] for k in ("getup", "joystick")}}
               if float(teacher.get("bc_weight", 0.0)) > 0 else {})}   # student_finetune.uses_teacher's rule


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
    ckpt = checkpoints.kept_checkpoint(run_dir, env_steps, f"{env_steps} env steps")
    like = Path(like) if like else _env_fields_artifact(run_dir, state)
    if not like.exists():
        raise FileNotFoundError(f"{like}: no export of the run (nor of a --from run) to take the manifest's "
                                "env fields from (name one with --like)")
    manifest = {k: v for k, v in read_artifact(like)[3].items() if k not in ("content_hash", "provenance")}
    manifest["provenance"] = {**run_provenance(state, env_steps, state["preset"]),
                              "exported_from": f"{ckpt} (env fields from {like})"}
    params = checkpoints.load_checkpoint(ckpt)
    policy, rule = exported_policy(params[1], state["ppo_config"])
    manifest.update(name=name, output_rule=rule,
                    trained=exported_as_trained(int(env_steps), state["preset"], state["env_config"]))
    path = run_dir / f"{name}.safetensors"
    export_brax_ppo((params[0], policy), manifest, path,
                    observations_normalized=bool(state["ppo_config"]["normalize_observations"]))
    return path


def exported_as_trained(steps: int, preset: str, env_config) -> bool:
    """Whether a run's export may say `trained: true`: real steps, a real preset and no assist stage."""
    from training.envs import assists
    return steps > 0 and preset != "toy" and not assists.assisted(env_config)
