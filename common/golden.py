"""The project's manifest defaults and the golden vectors that pin the C++ runtime to common/observation.py:
a seeded random policy (`random_policy.safetensors`) and its per-tick outputs on seeded states.

Golden vectors: inputs are rounded to float32 (what the bus and the C++ runtime carry), then every
expected value is computed in float64 from the float32 weights, so the reference carries no float32
rounding of its own; the C++ float32 pipeline must land within `tolerance` (absolute, per element).
Regenerate with `python -m common.golden tests/golden`.
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from common import observation as obsdef
from common.artifact import SCHEMA_VERSION, read_artifact, write_artifact
from messages import contract

# Home pose [rad], joint order (t1_facts.md §3, Menagerie/Playground `home` keyframe).
HOME_POSE_RAD: tuple[float, ...] = (
    0.0, 0.0,
    0.0, -1.4, 0.0, -0.4,
    0.0, 1.4, 0.0, 0.4,
    0.0,
    -0.2, 0.0, 0.0, 0.4, -0.2, 0.0,
    -0.2, 0.0, 0.0, 0.4, -0.2, 0.0)
# Defaults for manifests (the env config overrides them when exporting a trained policy).
DEFAULT_ACTION_SCALE = 0.5          # target = home + 0.5·action [rad]: ±0.5 rad around home at |a| = 1
DEFAULT_GAIT_FREQUENCY_HZ = 1.5     # Playground's T1 sim2sim gait frequency
DEFAULT_PHASE_FREEZE_COMMAND_NORM = 0.01  # Playground's "standing still" command-norm threshold
DEFAULT_COMMAND_RANGES = {"vx": [-1.0, 1.0], "vy": [-0.8, 0.8], "yaw_rate": [-1.0, 1.0]}

# The golden random policy.
GOLDEN_SEED = 20250211
GOLDEN_HIDDEN = (512, 256, 128)
GOLDEN_ACTIVATION = "swish"
GOLDEN_NUM_CASES = 24
GOLDEN_TOLERANCE = 1e-5
GOLDEN_ARTIFACT = "random_policy.safetensors"
GOLDEN_VECTORS = "golden_vectors.json"
GOLDEN_COMMAND = "python -m common.golden tests/golden"
# Typical spread of the velocity terms (gyro [rad/s], joint_vel [rad/s]) so the golden normaliser looks
# like a trained one: normalised values stay O(10), where float32 keeps ~1e-6 absolute precision.
GOLDEN_TERM_STD_SCALE = {"gyro": 2.0, "joint_vel": 5.0}


def pd_gains_from_model() -> tuple[list[float], list[float], str]:
    """(kp, kd, source): the one shared gain set, the model's custom numerics pd_kp / pd_kd."""
    from common import model as t1model
    kp, kd = t1model.pd_gains(t1model.load_model())
    return kp.tolist(), kd.tolist(), "common/models/t1.xml custom numerics pd_kp/pd_kd"


def base_manifest(**overrides) -> dict[str, Any]:
    """A complete manifest with the project defaults; pass fields to override (name, trained, ...)."""
    kp, kd, _ = pd_gains_from_model()
    manifest = {
        "schema_version": SCHEMA_VERSION, "name": "policy", "activation": "swish",
        "output_rule": "tanh_normal", "obs_terms": [list(t) for t in obsdef.TERMS_UNION],
        "joint_names": list(contract.JOINT_NAMES), "default_pose": list(HOME_POSE_RAD),
        "action_scale": DEFAULT_ACTION_SCALE, "kp": kp, "kd": kd, "control_dt": contract.POLICY_PERIOD_S,
        "gait_frequency": DEFAULT_GAIT_FREQUENCY_HZ,
        "phase_freeze_command_norm": DEFAULT_PHASE_FREEZE_COMMAND_NORM,
        "command_ranges": {k: list(v) for k, v in DEFAULT_COMMAND_RANGES.items()}, "trained": False,
        "provenance": {"git_commit": "unknown", "steps": 0, "date": "unknown", "command": "unknown"},
    }
    manifest.update(overrides)
    return manifest


def _f32(x) -> np.ndarray:
    """Round to float32 (the C++ side's precision), returned as float64 for the reference maths."""
    return np.asarray(x, dtype=np.float32).astype(np.float64)


def random_policy(rng: np.random.Generator, terms, hidden=GOLDEN_HIDDEN):
    """Random-init tanh_normal MLP (W ~ N(0, 1/in), small random biases) and a non-trivial normaliser."""
    obs_size = obsdef.observation_size(terms)
    term_scale = np.concatenate([np.full(size, GOLDEN_TERM_STD_SCALE.get(name, 1.0)) for name, size in terms])
    sizes = [obs_size, *hidden, 2 * contract.NUM_JOINTS]
    layers = [(rng.normal(0.0, 1.0 / math.sqrt(n_in), (n_out, n_in)).astype(np.float32),
               rng.normal(0.0, 0.1, n_out).astype(np.float32)) for n_in, n_out in zip(sizes[:-1], sizes[1:])]
    obs_mean = rng.normal(0.0, 0.2, obs_size).astype(np.float32)
    obs_std = (rng.uniform(0.5, 2.0, obs_size) * term_scale).astype(np.float32)
    return layers, obs_mean, obs_std


def _random_unit_quat(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def _axis_angle_quat(axis, angle_rad):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle_rad / 2)], math.sin(angle_rad / 2) * axis])


def golden_states(rng: np.random.Generator, num_cases: int, default_pose) -> list[dict[str, np.ndarray]]:
    """Seeded states covering upright, upside-down, pitched/rolled/yawed, random orientations, large
    velocities, zero command and the initial gait phase. Every value is float32-representable."""
    special_quats = [
        (1, 0, 0, 0),                                   # upright
        (0, 1, 0, 0),                                   # upside down (roll π)
        _axis_angle_quat((0, 1, 0), math.pi / 2),       # pitched 90° nose down
        _axis_angle_quat((0, 1, 0), -math.pi / 2),      # pitched 90° nose up
        _axis_angle_quat((1, 0, 0), math.pi / 2),       # rolled 90° (lying on the side)
        _axis_angle_quat((0, 0, 1), 2.0),               # yawed only: gravity stays (0, 0, −1)
        _axis_angle_quat((1, 1, 0), 0.3),               # mild tilt
        (0, 0, 0, 1),                                   # yaw π
    ]
    states = []
    for k in range(num_cases):
        quat = special_quats[k] if k < len(special_quats) else _random_unit_quat(rng)
        large = k % 3 == 2  # every third case: violent motion (a fall, a getup)
        vel_scale = 25.0 if large else 3.0   # rad/s
        command = np.zeros(3) if k % 4 == 0 else rng.uniform([-1, -0.8, -1], [1, 0.8, 1])
        gait_phase = obsdef.initial_gait_phase() if k == 1 else rng.uniform(-math.pi, math.pi, 2)
        states.append({
            "imu_quat": _f32(quat),
            "gyro": _f32(rng.normal(0.0, vel_scale / 3, 3)),
            "command": _f32(command),
            "q": _f32(np.asarray(default_pose) + rng.uniform(-1.0, 1.0, contract.NUM_JOINTS)),
            "dq": _f32(rng.normal(0.0, vel_scale / 2, contract.NUM_JOINTS)),
            "last_action": _f32(rng.uniform(-1.0, 1.0, contract.NUM_JOINTS)),
            "gait_phase": _f32(gait_phase),
        })
    return states


def _reference(manifest, layers, obs_mean, obs_std, case, dtype):
    """The per-tick pipeline in `dtype` (float64: the reference; float32: what the C++ does)."""
    cast = lambda a: np.asarray(a, dtype=dtype)  # noqa: E731
    state = obsdef.ObservationState(
        imu_quat=cast(case["imu_quat"]), gyro=cast(case["gyro"]), command=cast(case["command"]),
        q=cast(case["q"]), dq=cast(case["dq"]), default_pose=cast(manifest["default_pose"]),
        last_action=cast(case["last_action"]), gait_phase=cast(case["gait_phase"]))
    return obsdef.policy_step(manifest["obs_terms"], state, [(cast(w), cast(b)) for w, b in layers],
                              cast(obs_mean), cast(obs_std), manifest["activation"], manifest["output_rule"],
                              dtype(manifest["action_scale"]))


def golden_document(artifact_path) -> tuple[dict, float]:
    """(golden_vectors.json content, max |float32 pipeline − float64 reference| over every output)."""
    layers, obs_mean, obs_std, manifest = read_artifact(artifact_path)
    rng = np.random.default_rng(GOLDEN_SEED + 1)
    cases, worst = [], 0.0
    for case in golden_states(rng, GOLDEN_NUM_CASES, manifest["default_pose"]):
        ref = _reference(manifest, layers, obs_mean, obs_std, case, np.float64)
        f32 = _reference(manifest, layers, obs_mean, obs_std, case, np.float32)
        worst = max(worst, *(float(np.max(np.abs(ref[k] - f32[k]))) for k in ref))
        cases.append({**{k: v.tolist() for k, v in case.items()}, **{k: v.tolist() for k, v in ref.items()}})
    return {"artifact": Path(artifact_path).name, "tolerance": GOLDEN_TOLERANCE, "cases": cases}, worst


def write_golden(directory) -> list[Path]:
    """Write the random policy artifact and its golden vectors into `directory` (deterministic)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(GOLDEN_SEED)
    layers, obs_mean, obs_std = random_policy(rng, obsdef.TERMS_UNION)
    manifest = base_manifest(
        name="golden_random_policy", activation=GOLDEN_ACTIVATION, trained=False,
        provenance={"git_commit": "n/a (seeded random init)", "steps": 0, "date": "n/a",
                    "command": GOLDEN_COMMAND})
    artifact_path = directory / GOLDEN_ARTIFACT
    write_artifact(artifact_path, layers, obs_mean, obs_std, manifest)
    document, worst = golden_document(artifact_path)
    if worst > GOLDEN_TOLERANCE / 2:
        raise RuntimeError(f"golden: float32 pipeline deviates {worst:.3g} from float64, too close to the "
                           f"tolerance {GOLDEN_TOLERANCE}")
    vectors_path = directory / GOLDEN_VECTORS
    vectors_path.write_text(json.dumps(document, indent=1) + "\n")
    return [artifact_path, vectors_path]


def main(argv: Sequence[str] | None = None) -> int:
    import argparse
    parser = argparse.ArgumentParser(prog="python -m common.golden", description=__doc__.split("\n")[0])
    parser.add_argument("directory", help="write random_policy.safetensors and golden_vectors.json here")
    args = parser.parse_args(argv)
    for path in write_golden(args.directory):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
