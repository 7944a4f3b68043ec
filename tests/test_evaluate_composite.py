"""The batch evaluator's composite (training/evaluate.py CompositePolicy): the runtime's --policy-upright
mode, the seed's chapter-6 baseline (getup policy below waist 0.5 m, joystick policy above)."""
from pathlib import Path

import numpy as np
import pytest

from training import observation as obsdef
from training.evaluate import ArtifactPolicy, CompositePolicy, load_policy
from training.teacher import WAIST_SWITCH_HEIGHT_M

ROOT = Path(__file__).resolve().parents[1]
GETUP = ROOT / "policies" / "getup_baseline.safetensors"
UPRIGHT = ROOT / "policies" / "joystick.safetensors"


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


def test_composite_acts_with_the_member_the_waist_height_selects():
    composite = load_policy(f"{GETUP},{UPRIGHT}")
    obs_state = _obs_state(np.random.default_rng(0))
    below, above = WAIST_SWITCH_HEIGHT_M - 0.05, WAIST_SWITCH_HEIGHT_M + 0.05
    for waist, member, params in ((below, composite.getup, composite.params[0]),
                                  (above, composite.upright, composite.params[1])):
        action, q_des = composite.act(composite.params, obs_state, np.float32(waist))
        want_action, want_q = member.act(params, obs_state, np.float32(waist))
        np.testing.assert_allclose(np.asarray(action), np.asarray(want_action), rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(np.asarray(q_des), np.asarray(want_q), rtol=1e-6, atol=1e-6)
    # each member through its own action map: the same action would give different targets
    a_g, q_g = composite.getup.act(composite.params[0], obs_state, 0.0)
    a_u, q_u = composite.upright.act(composite.params[1], obs_state, 0.0)
    assert not np.allclose(np.asarray(q_g), np.asarray(q_u))


@pytest.mark.slow
def test_composite_getup_evaluation_on_the_cpu_backend(tmp_path):
    from training.evaluate import evaluate
    report = evaluate(f"{GETUP},{UPRIGHT}", tmp_path, baseline=GETUP, seeds=2, seconds=0.2, backend="cpu")
    text = report.read_text()
    assert "composite (getup below waist 0.5 m, upright above)" in text and "| success rate |" in text
    rows = (tmp_path / "per_env.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 2
