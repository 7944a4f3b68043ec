"""Policy artifact (`*.safetensors`, policies/ARTIFACT.md schema 1): write, read, validate.

The reader parses the safetensors container itself (8-byte little-endian header length, JSON header,
raw data) rather than through the safetensors library, so that it checks exactly what the C++ loader
(runtime/src/artifact_loader.cpp) checks and every failure is a ValueError naming the field.
"""
from __future__ import annotations

import hashlib
import json
import math
import re
import struct
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from common import observation
from messages import contract

# The loop and policy rates are the contract's (messages/contract.json): a manifest's control_dt must be the
# policy period, contract.POLICY_PERIOD_S = LOOP_PERIOD_S × POLICY_DECIMATION.
RUNTIME_LOOP_DT_S = contract.LOOP_PERIOD_S   # the same value under the name training/envs/starts reads

# Motor classes and their gain ceilings [N·m/rad], [N·m·s/rad]: the kp/kd ranges of the CAN command
# packing, read from firmware_like's protocol header (the one source; the C++ loader includes it).
PROTOCOL_HEADER = Path(__file__).resolve().parent.parent / "firmware_like" / "include" / "t1_motor_protocol.h"
MOTOR_CLASS_OF_JOINT: dict[str, str] = {
    "AAHead_yaw": "head", "Head_pitch": "head",
    **{f"{s}_{j}": "arm" for s in ("Left", "Right")
       for j in ("Shoulder_Pitch", "Shoulder_Roll", "Elbow_Pitch", "Elbow_Yaw")},
    "Waist": "waist",
    **{f"{s}_Hip_{a}": "hip" for s in ("Left", "Right") for a in ("Pitch", "Roll", "Yaw")},
    **{f"{s}_Knee_Pitch": "knee" for s in ("Left", "Right")},
    **{f"{s}_Ankle_{a}": "ankle" for s in ("Left", "Right") for a in ("Pitch", "Roll")},
}


def _protocol_constant(name: str) -> float:
    text = PROTOCOL_HEADER.read_text()
    match = re.search(rf"#define\s+{name}\s+([0-9.eE+-]+)f?\b", text)
    if match is None:
        raise RuntimeError(f"{PROTOCOL_HEADER}: no #define {name}")
    return float(match.group(1))


# Documented maxima of manifest numbers (policies/ARTIFACT.md): the C++ loader's constants, read from its
# header (one source), so Python never writes a file the runtime would refuse.
RUNTIME_CONSTANTS_HEADER = Path(__file__).resolve().parent.parent / "runtime" / "include" / "t1rt" / "constants.hpp"


def _runtime_constant(name: str, kind: str = "double") -> float:
    match = re.search(rf"constexpr\s+{kind}\s+{name}\s*=\s*([0-9.eE+-]+)\s*;", RUNTIME_CONSTANTS_HEADER.read_text())
    if match is None:
        raise RuntimeError(f"{RUNTIME_CONSTANTS_HEADER}: no constexpr {kind} {name}")
    return float(match.group(1))


SCHEMA_VERSION = int(_runtime_constant("kSchemaVersion", "int"))   # the artifact schema the loader handles
CONTROL_DT_TOLERANCE_S = _runtime_constant("kControlDtToleranceS")   # |control_dt − the policy period| allowed [s]


MAX_ACTION_SCALE_RAD = _runtime_constant("kMaxActionScaleRad")
MAX_GAIT_FREQUENCY_HZ = _runtime_constant("kMaxGaitFrequencyHz")
MAX_COMMAND_MAGNITUDE = _runtime_constant("kMaxCommandMagnitude")

# The header gives one range for all classes ("one gain set is shared by all policies").
KP_MAX_BY_CLASS: dict[str, float] = {c: _protocol_constant("T1_KP_MAX") for c in set(MOTOR_CLASS_OF_JOINT.values())}
KD_MAX_BY_CLASS: dict[str, float] = {c: _protocol_constant("T1_KD_MAX") for c in set(MOTOR_CLASS_OF_JOINT.values())}
assert set(MOTOR_CLASS_OF_JOINT) == set(contract.JOINT_NAMES), "every joint needs a motor class"

METADATA_KEYS: tuple[str, ...] = (
    "schema_version", "name", "activation", "output_rule", "obs_terms", "joint_names", "default_pose",
    "action_scale", "kp", "kd", "control_dt", "gait_frequency", "phase_freeze_command_norm",
    "command_ranges", "trained", "provenance", "content_hash")
OPTIONAL_METADATA_KEYS: tuple[str, ...] = ("obs_scales",)
COMMAND_RANGE_KEYS: tuple[str, ...] = ("vx", "vy", "yaw_rate")
PROVENANCE_KEYS: dict[str, type] = {"git_commit": str, "steps": int, "date": str, "command": str}
HEADER_LENGTH_BYTES = 8
HEADER_ALIGNMENT_BYTES = 8  # the data section starts 8-byte aligned, as the safetensors library writes it
MAX_HEADER_BYTES = 100_000_000  # a larger header is a corrupt length field, not a policy


def content_hash(tensors: Mapping[str, np.ndarray]) -> str:
    """sha256 hex of the raw little-endian float32 bytes of every tensor, concatenated in byte-wise
    (ASCII) sorted tensor-name order (so "layers.10.weight" comes before "layers.2.weight")."""
    digest = hashlib.sha256()
    for name in sorted(tensors, key=lambda n: n.encode()):
        digest.update(np.ascontiguousarray(tensors[name], dtype="<f4").tobytes())
    return digest.hexdigest()


def _tensors_from(layers, obs_mean, obs_std) -> dict[str, np.ndarray]:
    tensors = {}
    for i, (w, b) in enumerate(layers):
        tensors[f"layers.{i}.weight"] = np.ascontiguousarray(w, dtype=np.float32)
        tensors[f"layers.{i}.bias"] = np.ascontiguousarray(b, dtype=np.float32)
    tensors["obs_mean"] = np.ascontiguousarray(obs_mean, dtype=np.float32)
    tensors["obs_std"] = np.ascontiguousarray(obs_std, dtype=np.float32)
    return tensors


def _plain(value):
    """numpy scalars/arrays → JSON-ready Python values (floats keep their float64 repr)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def encode_artifact(layers, obs_mean, obs_std, manifest: Mapping[str, Any]) -> bytes:
    """The artifact file's bytes. `manifest` holds every metadata key except content_hash (computed)."""
    tensors = _tensors_from(layers, obs_mean, obs_std)
    fields = {k: _plain(v) for k, v in manifest.items() if k != "content_hash"}
    fields["content_hash"] = content_hash(tensors)
    missing = [k for k in METADATA_KEYS if k not in fields]
    if missing:
        raise ValueError(f"manifest: missing field(s) {missing}")
    unknown = sorted(set(fields) - set(METADATA_KEYS) - set(OPTIONAL_METADATA_KEYS))
    if unknown:
        raise ValueError(f"manifest: unknown field(s) {unknown}")
    metadata = {k: json.dumps(fields[k], separators=(",", ":")) for k in sorted(fields)}
    data = _serialize_container(tensors, metadata)
    validate_artifact_bytes(data)  # never write a file the runtime would refuse
    return data


def _serialize_container(tensors: Mapping[str, np.ndarray], metadata: Mapping[str, str]) -> bytes:
    """safetensors bytes, deterministic: tensors and metadata keys in sorted order (the safetensors
    library writes its metadata map in hash order, so two writes of one policy would differ)."""
    header: dict[str, Any] = {"__metadata__": dict(sorted(metadata.items()))}
    offset, blobs = 0, []
    for name in sorted(tensors, key=lambda n: n.encode()):
        blob = np.ascontiguousarray(tensors[name], dtype="<f4").tobytes()
        header[name] = {"dtype": "F32", "shape": list(tensors[name].shape),
                        "data_offsets": [offset, offset + len(blob)]}
        blobs.append(blob)
        offset += len(blob)
    header_bytes = json.dumps(header, separators=(",", ":")).encode("utf-8")
    header_bytes += b" " * (-len(header_bytes) % HEADER_ALIGNMENT_BYTES)  # safetensors pads with spaces
    return struct.pack("<Q", len(header_bytes)) + header_bytes + b"".join(blobs)


def write_artifact(path, layers: Sequence[tuple[Any, Any]], obs_mean, obs_std, manifest: Mapping[str, Any]) -> str:
    """Write a validated artifact; returns its content_hash."""
    data = encode_artifact(layers, obs_mean, obs_std, manifest)
    Path(path).write_bytes(data)
    return read_artifact_bytes(data)[3]["content_hash"]


def stitched_teacher(manifest: Mapping[str, Any]) -> dict[str, str] | None:
    """{"getup": path, "joystick": path}: the teacher a distilled or fine-tuned student names in its provenance
    (paths as given to training), or None for an artifact trained without one."""
    teacher = manifest.get("provenance", {}).get("teacher")
    return teacher if isinstance(teacher, dict) and {"getup", "joystick"} <= set(teacher) else None


def read_artifact(path):
    """→ (layers [(W (out,in), b)], obs_mean, obs_std, manifest dict). ValueError naming the field."""
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        raise ValueError(f"file: cannot read {path}: {e}") from e
    return read_artifact_bytes(data)


def artifact_problem(path) -> str | None:
    """None when `path` is a readable, valid policy artifact; else one line that names it and what is wrong
    (what every command taking a --policy prints before it starts anything)."""
    p = Path(path)
    if p.is_dir():
        return f"{path}: a folder, not an artifact file (*.safetensors)"
    if not p.exists():
        return f"{path}: no such file"
    try:
        read_artifact(p)
    except ValueError as e:
        return f"{path}: not a policy artifact ({e})"
    return None


def validate_artifact_bytes(data: bytes) -> None:
    read_artifact_bytes(data)


# ---------------------------------------------------------------- reading and validation
def _parse_container(data: bytes) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    if len(data) < HEADER_LENGTH_BYTES:
        raise ValueError(f"file: truncated ({len(data)} bytes, shorter than the 8-byte header length)")
    (header_len,) = struct.unpack("<Q", data[:HEADER_LENGTH_BYTES])
    if header_len > MAX_HEADER_BYTES or HEADER_LENGTH_BYTES + header_len > len(data):
        raise ValueError(f"file: truncated or corrupt (header length {header_len}, file {len(data)} bytes)")
    try:
        header = json.loads(data[HEADER_LENGTH_BYTES:HEADER_LENGTH_BYTES + header_len].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"header: not valid JSON ({e})") from e
    if not isinstance(header, dict):
        raise ValueError("header: not a JSON object")
    metadata = header.pop("__metadata__", None)
    if not isinstance(metadata, dict) or not all(isinstance(v, str) for v in metadata.values()):
        raise ValueError("__metadata__: missing or not a string → string map")
    body = data[HEADER_LENGTH_BYTES + header_len:]
    tensors = {}
    for name, info in header.items():
        if not isinstance(info, dict) or info.get("dtype") != "F32":
            got = info.get("dtype") if isinstance(info, dict) else info
            raise ValueError(f"{name}: dtype must be F32, got {got!r}")
        shape, offsets = info.get("shape"), info.get("data_offsets")
        if (not isinstance(shape, list) or not all(isinstance(s, int) and s >= 0 for s in shape)
                or not isinstance(offsets, list) or len(offsets) != 2):
            raise ValueError(f"{name}: bad shape/data_offsets in the header")
        begin, end = offsets
        count = int(np.prod(shape)) if shape else 1
        if end > len(body):
            raise ValueError(f"file: truncated ({name} ends at byte {end}, data has {len(body)})")
        if not 0 <= begin <= end or end - begin != 4 * count:
            raise ValueError(f"{name}: data_offsets {offsets} do not match shape {shape}")
        tensors[name] = np.frombuffer(body, dtype="<f4", count=count, offset=begin).reshape(shape).copy()
    return tensors, metadata


def _fail(field: str, why: str):
    raise ValueError(f"{field}: {why}")


def _finite_list(manifest, key, length=None):
    value = manifest[key]
    if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        _fail(key, "must be a list of numbers")
    if length is not None and len(value) != length:
        _fail(key, f"has {len(value)} entries, expected {length}")
    if not all(math.isfinite(v) for v in value):
        _fail(key, "contains a non-finite value")
    return np.asarray(value, dtype=np.float64)


def _finite_number(manifest, key):
    value = manifest[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        _fail(key, f"must be a finite number, got {value!r}")
    return float(value)


def _check_manifest(manifest: dict) -> None:
    if manifest["schema_version"] != SCHEMA_VERSION or isinstance(manifest["schema_version"], bool):
        _fail("schema_version", f"is {manifest['schema_version']!r}, this reader knows {SCHEMA_VERSION}")
    if not isinstance(manifest["name"], str) or not manifest["name"]:
        _fail("name", "must be a non-empty string")
    if manifest["activation"] not in observation.ACTIVATIONS:
        _fail("activation", f"{manifest['activation']!r} is not one of {observation.ACTIVATIONS}")
    if manifest["output_rule"] not in observation.OUTPUT_RULES:
        _fail("output_rule", f"{manifest['output_rule']!r} is not one of {observation.OUTPUT_RULES}")
    if not isinstance(manifest["obs_terms"], list):
        _fail("obs_terms", "must be a list of [name, size]")
    observation.check_terms(manifest["obs_terms"])  # raises "obs_terms: ..."
    names = manifest["joint_names"]
    if not isinstance(names, list) or len(names) != contract.NUM_JOINTS:
        _fail("joint_names", f"must be a list of {contract.NUM_JOINTS} names (messages/contract.json)")
    for i, (got, want) in enumerate(zip(names, contract.JOINT_NAMES)):
        if got != want:
            _fail("joint_names", f"entry {i} is {got!r}, the runtime order (messages/contract.json) has {want!r}")
    _finite_list(manifest, "default_pose", contract.NUM_JOINTS)
    scale = manifest["action_scale"]
    if isinstance(scale, list):
        scales = _finite_list(manifest, "action_scale", contract.NUM_JOINTS)
    else:
        scales = np.array([_finite_number(manifest, "action_scale")])
    if not np.all((scales > 0.0) & (scales <= MAX_ACTION_SCALE_RAD)):
        _fail("action_scale", f"must be in (0, {MAX_ACTION_SCALE_RAD}] rad per unit action (the joint range "
                              "bounds it further in the runtime)")
    for key, limits in (("kp", KP_MAX_BY_CLASS), ("kd", KD_MAX_BY_CLASS)):
        gains = _finite_list(manifest, key, contract.NUM_JOINTS)
        for joint, gain in zip(contract.JOINT_NAMES, gains):
            ceiling = limits[MOTOR_CLASS_OF_JOINT[joint]]
            if not 0.0 <= gain <= ceiling:
                _fail(key, f"{joint} = {gain} is outside [0, {ceiling}] (motor class "
                           f"{MOTOR_CLASS_OF_JOINT[joint]})")
    dt = _finite_number(manifest, "control_dt")
    if abs(dt - contract.POLICY_PERIOD_S) > CONTROL_DT_TOLERANCE_S:
        _fail("control_dt", f"is {dt} s, the runtime needs {contract.LOOP_PERIOD_S} s × {contract.POLICY_DECIMATION} "
                            f"= {contract.POLICY_PERIOD_S} s")
    if not 0.0 < _finite_number(manifest, "gait_frequency") <= MAX_GAIT_FREQUENCY_HZ:
        _fail("gait_frequency", f"must be in (0, {MAX_GAIT_FREQUENCY_HZ}] Hz")
    if not 0.0 <= _finite_number(manifest, "phase_freeze_command_norm") <= MAX_COMMAND_MAGNITUDE:
        _fail("phase_freeze_command_norm", f"must be in [0, {MAX_COMMAND_MAGNITUDE}]")
    ranges = manifest["command_ranges"]
    if not isinstance(ranges, dict) or sorted(ranges) != sorted(COMMAND_RANGE_KEYS):
        _fail("command_ranges", f"must be an object with exactly the keys {COMMAND_RANGE_KEYS}")
    for key, pair in ranges.items():
        if (not isinstance(pair, list) or len(pair) != 2 or not all(isinstance(v, (int, float)) and
                not isinstance(v, bool) and math.isfinite(v) and abs(v) <= MAX_COMMAND_MAGNITUDE for v in pair)
                or pair[0] > pair[1]):
            _fail("command_ranges", f"{key} must be [low, high] finite with low ≤ high and |bound| ≤ "
                                    f"{MAX_COMMAND_MAGNITUDE}, got {pair!r}")
    if not isinstance(manifest["trained"], bool):
        _fail("trained", "must be true or false")
    prov = manifest["provenance"]
    if not isinstance(prov, dict):
        _fail("provenance", "must be an object")
    for key, kind in PROVENANCE_KEYS.items():
        if key not in prov or not isinstance(prov[key], kind) or isinstance(prov[key], bool):
            _fail("provenance", f"{key} missing or not a {kind.__name__}")
    if prov["steps"] < 0:
        _fail("provenance", "steps must be ≥ 0")
    if not isinstance(manifest["content_hash"], str):
        _fail("content_hash", "must be a hex string")


def _check_tensors(tensors: dict, manifest: dict):
    num_layers = sum(1 for n in tensors if n.startswith("layers.") and n.endswith(".weight"))
    if num_layers == 0:
        _fail("layers.0.weight", "missing (no layers)")
    expected = {f"layers.{i}.{p}" for i in range(num_layers) for p in ("weight", "bias")} | {"obs_mean", "obs_std"}
    for name in sorted(expected - set(tensors)):
        _fail(name, "missing tensor")
    for name in sorted(set(tensors) - expected):
        _fail(name, "unexpected tensor")
    obs_size = observation.observation_size(manifest["obs_terms"])
    action_size = contract.NUM_JOINTS
    layers = []
    width = obs_size
    for i in range(num_layers):
        w, b = tensors[f"layers.{i}.weight"], tensors[f"layers.{i}.bias"]
        if w.ndim != 2 or w.shape[1] != width:
            _fail(f"layers.{i}.weight", f"shape {w.shape}, expected (out, {width})")
        if b.shape != (w.shape[0],):
            _fail(f"layers.{i}.bias", f"shape {b.shape}, expected ({w.shape[0]},)")
        width = w.shape[0]
        layers.append((w, b))
    out_needed = 2 * action_size if manifest["output_rule"] == "tanh_normal" else action_size
    if width != out_needed:
        _fail(f"layers.{num_layers - 1}.weight", f"outputs {width}, output_rule {manifest['output_rule']!r} "
                                                 f"with {action_size} joints needs {out_needed}")
    for name in ("obs_mean", "obs_std"):
        if tensors[name].shape != (obs_size,):
            _fail(name, f"shape {tensors[name].shape}, expected ({obs_size},) = sum of obs_terms sizes")
    for name in sorted(tensors):
        if not np.all(np.isfinite(tensors[name])):
            _fail(name, "contains NaN or Inf")
    if not np.all(tensors["obs_std"] > 0):
        _fail("obs_std", "must be strictly positive")
    if content_hash(tensors) != manifest["content_hash"]:
        _fail("content_hash", "does not match the tensor bytes")
    return layers


def read_artifact_bytes(data: bytes):
    tensors, raw_metadata = _parse_container(data)
    manifest = {}
    for key in METADATA_KEYS:
        if key not in raw_metadata:
            _fail(key, "missing from __metadata__")
    for key in sorted(set(raw_metadata) - set(METADATA_KEYS) - set(OPTIONAL_METADATA_KEYS)):
        _fail(key, "unknown __metadata__ key")
    for key, text in raw_metadata.items():
        try:
            manifest[key] = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"{key}: value is not JSON text ({e})") from e
    _check_manifest(manifest)
    layers = _check_tensors(tensors, manifest)
    return layers, tensors["obs_mean"], tensors["obs_std"], manifest
