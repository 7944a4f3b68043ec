"""Policy artifacts: round trip, content hash, brax PPO export parity, and the loader's rejections
(each with a message naming the field, as the C++ loader must)."""
import hashlib
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from common import artifact
from common import golden as export
from common import observation as ob
from messages import contract
from training.export import brax as training_export

GOLDEN = Path(__file__).resolve().parent / "golden" / export.GOLDEN_ARTIFACT
N = contract.NUM_JOINTS


def _small_policy(seed=0, hidden=(16, 8)):
    return export.random_policy(np.random.default_rng(seed), ob.TERMS_UNION, hidden)


def _write(tmp_path, name="p.safetensors", **manifest_overrides):
    layers, mean, std = _small_policy()
    path = tmp_path / name
    artifact.write_artifact(path, layers, mean, std, export.base_manifest(**manifest_overrides))
    return path


def test_round_trip(tmp_path):
    layers, mean, std = _small_policy()
    manifest = export.base_manifest(name="rt", trained=False)
    path = tmp_path / "rt.safetensors"
    digest = artifact.write_artifact(path, layers, mean, std, manifest)
    r_layers, r_mean, r_std, r_manifest = artifact.read_artifact(path)
    assert len(r_layers) == len(layers)
    for (w, b), (rw, rb) in zip(layers, r_layers):
        np.testing.assert_array_equal(w, rw)
        np.testing.assert_array_equal(b, rb)
    np.testing.assert_array_equal(mean, r_mean)
    np.testing.assert_array_equal(std, r_std)
    for key, value in manifest.items():
        assert r_manifest[key] == (list(map(list, value)) if key == "obs_terms" else value), key
    assert r_manifest["content_hash"] == digest
    # The safetensors library reads the file too (same container as the C++ side parses).
    from safetensors import safe_open
    with safe_open(str(path), "np") as f:
        assert json.loads(f.metadata()["content_hash"]) == digest
        np.testing.assert_array_equal(f.get_tensor("layers.0.weight"), layers[0][0])


def test_content_hash_is_sha256_of_sorted_tensor_bytes(tmp_path):
    layers, mean, std = _small_policy()
    tensors = {"obs_mean": mean, "obs_std": std}
    for i, (w, b) in enumerate(layers):
        tensors[f"layers.{i}.weight"], tensors[f"layers.{i}.bias"] = w, b
    expected = hashlib.sha256(b"".join(tensors[k].astype("<f4").tobytes() for k in sorted(tensors))).hexdigest()
    assert artifact.write_artifact(tmp_path / "h.safetensors", layers, mean, std, export.base_manifest()) == expected
    assert artifact.read_artifact(GOLDEN)[3]["content_hash"] == artifact.content_hash(
        {k: v for k, v in _tensor_map(GOLDEN).items()})


def _tensor_map(path):
    layers, mean, std, _ = artifact.read_artifact(path)
    out = {"obs_mean": mean, "obs_std": std}
    for i, (w, b) in enumerate(layers):
        out[f"layers.{i}.weight"], out[f"layers.{i}.bias"] = w, b
    return out


# ---------------------------------------------------------------- rejections
def _split(path):
    data = Path(path).read_bytes()
    (n,) = struct.unpack("<Q", data[:8])
    return json.loads(data[8:8 + n]), data[8 + n:]


def _join(header, body):
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 8)
    return struct.pack("<Q", len(text)) + text + body


def _with_metadata(path, **changes):
    header, body = _split(path)
    for key, value in changes.items():
        header["__metadata__"][key] = json.dumps(value)
    return _join(header, body)


def _expect(data, tmp_path, field):
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(data)
    with pytest.raises(ValueError, match=field):
        artifact.read_artifact(bad)


def test_rejects_truncated_file(tmp_path):
    data = _write(tmp_path).read_bytes()
    _expect(data[:-100], tmp_path, "truncated")
    _expect(data[:5], tmp_path, "truncated")


def test_rejects_bad_json_header(tmp_path):
    data = bytearray(_write(tmp_path).read_bytes())
    data[8] = ord("[")  # the header no longer parses as the JSON it was
    data[9:12] = b"{{{"
    _expect(bytes(data), tmp_path, "header")


def test_rejects_missing_tensor(tmp_path):
    header, body = _split(_write(tmp_path))
    del header["obs_std"]
    _expect(_join(header, body), tmp_path, "obs_std")


def test_rejects_wrong_shape(tmp_path):
    header, body = _split(_write(tmp_path))
    header["layers.1.weight"]["shape"] = header["layers.1.weight"]["shape"][::-1]  # (in, out): not transposed
    _expect(_join(header, body), tmp_path, "layers.1.weight")


def test_rejects_nan_weight(tmp_path):
    path = _write(tmp_path)
    header, body = _split(path)
    begin = header["layers.0.weight"]["data_offsets"][0]
    body = body[:begin] + np.float32(np.nan).tobytes() + body[begin + 4:]
    _expect(_join(header, body), tmp_path, "layers.0.weight")


def test_rejects_wrong_joint_order(tmp_path):
    names = list(contract.JOINT_NAMES)
    names[11], names[17] = names[17], names[11]
    _expect(_with_metadata(_write(tmp_path), joint_names=names), tmp_path, "joint_names")


def test_rejects_wrong_dt(tmp_path):
    _expect(_with_metadata(_write(tmp_path), control_dt=0.01), tmp_path, "control_dt")


def test_rejects_gains_over_limits(tmp_path):
    path = _write(tmp_path)
    kp = [artifact.KP_MAX_BY_CLASS["knee"] + 1.0] * N
    _expect(_with_metadata(path, kp=kp), tmp_path, "kp")
    _expect(_with_metadata(path, kd=[-1.0] * N), tmp_path, "kd")


@pytest.mark.parametrize("changes, field", [
    ({"schema_version": 2}, "schema_version"),
    ({"activation": "gelu"}, "activation"),
    ({"output_rule": "linear"}, "layers.2.weight"),   # 46 outputs but linear needs 23
    ({"obs_terms": [["gyro", 3]]}, "layers.0.weight"),
    ({"default_pose": [0.0] * 22}, "default_pose"),
    ({"trained": "no"}, "trained"),
    ({"provenance": {"git_commit": "x"}}, "provenance"),
    ({"command_ranges": {"vx": [1, -1], "vy": [0, 0], "yaw_rate": [0, 0]}}, "command_ranges"),
    ({"content_hash": "0" * 64}, "content_hash"),
    ({"action_scale": 1e6}, "action_scale"),            # the runtime's documented maxima
    ({"action_scale": -0.5}, "action_scale"),
    ({"gait_frequency": 1e4}, "gait_frequency"),
    ({"command_ranges": {"vx": [-1e9, 1e9], "vy": [0, 0], "yaw_rate": [0, 0]}}, "command_ranges"),
])
def test_rejects_other_bad_fields(tmp_path, changes, field):
    _expect(_with_metadata(_write(tmp_path), **changes), tmp_path, field)


def test_writer_refuses_incomplete_manifest(tmp_path):
    layers, mean, std = _small_policy()
    manifest = export.base_manifest()
    del manifest["kd"]
    with pytest.raises(ValueError, match="kd"):
        artifact.write_artifact(tmp_path / "x.safetensors", layers, mean, std, manifest)


def test_gain_limits_come_from_the_firmware_header():
    text = artifact.PROTOCOL_HEADER.read_text()
    assert f"{artifact.KP_MAX_BY_CLASS['hip']:g}" in text and "T1_KD_MAX" in text


# ---------------------------------------------------------------- brax PPO
def test_export_brax_ppo_matches_brax_deterministic_policy(tmp_path):
    jax = pytest.importorskip("jax")
    ppo_networks = pytest.importorskip("brax.training.agents.ppo.networks")
    import jax.numpy as jnp
    from brax.training.acme import running_statistics, specs

    obs_size = ob.observation_size(ob.TERMS_UNION)
    networks = ppo_networks.make_ppo_networks(
        obs_size, N, preprocess_observations_fn=running_statistics.normalize,
        policy_hidden_layer_sizes=(64, 32, 32), value_hidden_layer_sizes=(16,))
    key_policy, key_value, key_obs, key_stats = jax.random.split(jax.random.PRNGKey(0), 4)
    normalizer = running_statistics.init_state(specs.Array((obs_size,), jnp.float32))
    # Non-trivial statistics, as after training: update with a scaled, shifted batch.
    sample = 3.0 * jax.random.normal(key_stats, (512, obs_size)) + 0.5
    normalizer = running_statistics.update(normalizer, sample)
    params = (normalizer, networks.policy_network.init(key_policy), networks.value_network.init(key_value))

    path = tmp_path / "brax.safetensors"
    training_export.export_brax_ppo(params, {"name": "brax_parity", "activation": "swish"}, path)
    layers, mean, std, manifest = artifact.read_artifact(path)
    assert [w.shape for w, _ in layers] == [(64, obs_size), (32, 64), (32, 32), (2 * N, 32)]

    policy = ppo_networks.make_inference_fn(networks)(params, deterministic=True)
    obs = np.asarray(jax.random.normal(key_obs, (64, obs_size)) * 2.0, dtype=np.float32)
    brax_action = np.asarray(policy(jnp.asarray(obs), jax.random.PRNGKey(1))[0])
    runtime_action = ob.mlp_forward([(w.astype(np.float64), b.astype(np.float64)) for w, b in layers],
                                    ob.normalize(obs.astype(np.float64), mean.astype(np.float64),
                                                 std.astype(np.float64)),
                                    manifest["activation"], manifest["output_rule"])
    np.testing.assert_allclose(runtime_action, brax_action, atol=1e-5)
