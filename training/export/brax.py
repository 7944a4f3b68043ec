"""Export policies to runtime artifacts (policies/ARTIFACT.md): brax PPO params → artifact (the manifest's
defaults and the golden vectors: common/golden.py)."""
from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from common import keyframe_chain
from common.artifact import read_artifact, write_artifact
from common.golden import base_manifest
from training.core import checkpoints
from training.envs import sagittal
from training.envs.policy_files import brax_policy_layers

# ---------------------------------------------------------------- brax PPO
NORMAL = "normal"   # ppo.policy_distribution of a fine-tuned student (training/distill/finetune.py)


def student_layers(policy) -> dict:
    """The "normal" PPO policy's params → brax MLP layers hidden_0..hidden_N (its mean: the exported student,
    output rule `linear`; the std is training's only)."""
    inner = policy["params"]
    mlp = inner["MLP_0"]
    layers = {f"hidden_{i}": mlp[f"hidden_{i}"] for i in range(len(mlp))}
    layers[f"hidden_{len(mlp)}"] = inner["Dense_0"]
    return {"params": layers}


def exported_policy(policy, ppo_config, env_config) -> tuple[dict, str]:
    """(policy params as the artifact's MLP, output rule) of a PPO run's policy: a fine-tuned student acts with
    its mean (`linear`), any other PPO policy is brax's tanh-normal (a sagittal one expanded to the 23 joints).
    env_config: the run's in today's schema (training/ppo/migration.py)."""
    if ppo_config["policy_distribution"] == NORMAL:
        return student_layers(policy), "linear"
    if env_config["action_space"] == "sagittal":
        return sagittal.expand_policy(policy), "tanh_normal"
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
    teacher = state["ppo_config"]["teacher"]
    return {"git_commit": checkpoints.git_commit(), "steps": int(steps), "date": checkpoints.utc_now(),
            "command": " ; ".join(c["command"] for c in state["calls"] if c["command"]) or "unknown",
            "device": last.get("device", "unknown"), "minutes": round(float(state["minutes"]), 2),
            "env_steps_per_s": state.get("env_steps_per_s", 0.0), "algorithm": "brax ppo",
            "preset": preset, "init": state.get("init") or "",
            **({"recipe": state["recipe"]} if state.get("recipe") else {}),
            **({"teacher": {k: teacher[k] for k in ("getup", "joystick")}}
               if float(teacher["bc_weight"]) > 0 else {})}   # student_finetune.uses_teacher's rule


def exported_as_trained(steps: int, preset: str) -> bool:
    """Whether a run's export may say `trained: true`: real steps and a real preset."""
    return steps > 0 and preset != "toy"


def ship_chain(policy: str, members: Mapping[str, Path], handover: str, state: dict,
               policies_root=checkpoints.POLICIES_ROOT) -> Path:
    """Ship a keyframe chain (common/keyframe_chain.py) as policies/<policy>/: each member artifact (role →
    artifact) beside the others, under its own name, a provenance row each in that folder's CARD.md, and the
    chain's manifest naming them and the rise → stand hand-over. Returns the folder."""
    folder = checkpoints.policy_dir(policy, policies_root)
    files = {role: ship_artifact(path, state, policies_root, folder).name for role, path in members.items()}
    keyframe_chain.write(folder, files, handover)
    return folder


def ship_artifact(artifact: Path, state: dict, policies_root=checkpoints.POLICIES_ROOT,
                  folder: Path | None = None) -> Path:
    """Copy the artifact to policies/<name>/<name>.safetensors (into `folder` where given: a chain's member) and
    append its provenance row to that folder's CARD.md (created from the card template for a new policy)."""
    manifest = read_artifact(artifact)[3]
    prov = manifest["provenance"]
    folder = Path(folder) if folder is not None else checkpoints.policy_dir(manifest["name"], policies_root)
    folder.mkdir(parents=True, exist_ok=True)
    shipped = folder / f"{manifest['name']}.safetensors"
    if shipped.resolve() != Path(artifact).resolve():
        shutil.copyfile(artifact, shipped)
    task = state["task"] + ("" if manifest["trained"] else " (SMOKE TEST, NOT TRAINED)")
    try:
        shown = shipped.resolve().relative_to(checkpoints.REPO_ROOT)
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
