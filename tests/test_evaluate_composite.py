"""The batch evaluator's composite (training/evaluation/batch.py CompositePolicy): the runtime's --policy-upright
mode, the seed's chapter-6 baseline (getup policy below waist 0.5 m, joystick policy above)."""
from pathlib import Path

import numpy as np
import pytest

from common import observation as obsdef
from messages.contract import WAIST_SWITCH_HEIGHT_M
from training.evaluation.artifact_policy import ArtifactPolicy, CompositePolicy, load_policy

ROOT = Path(__file__).resolve().parents[1]
GETUP = ROOT / "policies" / "getup_baseline" / "getup_baseline.safetensors"
UPRIGHT = ROOT / "policies" / "joystick" / "joystick.safetensors"


def _obs_state(rng):
    quat = np.array([1.0, 0.0, 0.0, 0.0], np.float32) + 0.1 * rng.standard_normal(4).astype(np.float32)
    return obsdef.ObservationState(
        imu_quat=quat, gyro=rng.standard_normal(3).astype(np.float32), command=np.zeros(3, np.float32),
        q=0.3 * rng.standard_normal(23).astype(np.float32), dq=rng.standard_normal(23).astype(np.float32),
        default_pose=np.zeros(23, np.float32), last_action=0.2 * rng.standard_normal(23).astype(np.float32),
        gait_phase=obsdef.initial_gait_phase(np).astype(np.float32))


def test_load_policy_reads_a_composite_and_names_a_bad_spec():
    composite = load_policy(f"{GETUP},{UPRIGHT}")
    assert isinstance(composite, CompositePolicy) and isinstance(load_policy(GETUP), ArtifactPolicy)
    assert composite.trained and composite.manifest["control_dt"] == composite.getup.manifest["control_dt"]
    assert "composite" in composite.describe() and str(UPRIGHT) in composite.describe()
    with pytest.raises(ValueError, match="GETUP.safetensors,UPRIGHT.safetensors"):
        load_policy(f"{GETUP},")
    with pytest.raises(ValueError, match="GETUP.safetensors,UPRIGHT.safetensors"):
        load_policy(f"{GETUP},{UPRIGHT},{UPRIGHT}")


def _body(waist_m):
    """The env's body readings the policies switch on (only the waist height matters to a composite)."""
    return {"trunk_height": np.float32(0.3), "waist_height": np.float32(waist_m), "up_z": np.float32(1.0)}


def _pair_state(obs_state, own_getup, own_upright):
    return obs_state._replace(last_action=(own_getup, own_upright))


def test_composite_acts_with_the_member_the_waist_height_selects():
    composite = load_policy(f"{GETUP},{UPRIGHT}")
    obs_state = _obs_state(np.random.default_rng(0))
    own_g, own_u = obs_state.last_action, -obs_state.last_action
    below, above = WAIST_SWITCH_HEIGHT_M - 0.05, WAIST_SWITCH_HEIGHT_M + 0.05
    for waist, member, params, own in ((below, composite.getup, composite.params[0], own_g),
                                       (above, composite.upright, composite.params[1], own_u)):
        _, q_des = composite.act(composite.params, _pair_state(obs_state, own_g, own_u), _body(waist))
        _, want_q = member.act(params, obs_state._replace(last_action=own), _body(waist))
        np.testing.assert_allclose(np.asarray(q_des), np.asarray(want_q), rtol=1e-6, atol=1e-6)
    # each member through its own action map: the same action would give different targets
    a_g, q_g = composite.getup.act(composite.params[0], obs_state, _body(0.0))
    a_u, q_u = composite.upright.act(composite.params[1], obs_state, _body(0.0))
    assert not np.allclose(np.asarray(q_g), np.asarray(q_u))


def test_each_member_reads_its_own_last_action_and_the_idle_one_the_applied_targets():
    """As the runtime's `follow` and the stitched teacher: the acting member keeps its action, the idle one
    reads the applied joint targets in its own map, clipped to ±1."""
    composite = load_policy(f"{GETUP},{UPRIGHT}")
    assert [np.shape(c) for c in composite.initial_last_action()] == [(obsdef.NUM_JOINTS,)] * 2
    obs_state = _obs_state(np.random.default_rng(1))
    state = _pair_state(obs_state, obs_state.last_action, obs_state.last_action)
    for waist, acting, idle in ((0.3, 0, 1), (0.7, 1, 0)):
        members = (composite.getup, composite.upright)
        next_own, q_target = composite.act(composite.params, state, _body(waist))
        next_own, q_target = [np.asarray(c) for c in next_own], np.asarray(q_target)
        a, _ = members[acting].act(composite.params[acting], obs_state._replace(last_action=obs_state.last_action),
                                   _body(waist))
        np.testing.assert_allclose(next_own[acting], np.asarray(a), rtol=1e-6, atol=1e-6)
        m = members[idle].manifest
        own = np.clip((q_target - np.asarray(m["default_pose"])) / np.asarray(m["action_scale"]), -1.0, 1.0)
        np.testing.assert_allclose(next_own[idle], own, rtol=1e-5, atol=1e-5)
    scales = [np.asarray(p.manifest["action_scale"]) * np.ones(obsdef.NUM_JOINTS) for p in members]
    assert not np.allclose(*scales), "the two shipped members' maps differ: the test must see it"


@pytest.mark.slow
def test_composite_getup_evaluation_on_the_cpu_backend(tmp_path):
    from training.evaluation.batch import evaluate
    report = evaluate(f"{GETUP},{UPRIGHT}", tmp_path, baseline=GETUP, seeds=2, seconds=0.2, backend="cpu")
    text = report.read_text()
    assert "composite (getup below waist 0.5 m, upright above)" in text and "| success rate |" in text
    rows = (tmp_path / "per_env.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 2
