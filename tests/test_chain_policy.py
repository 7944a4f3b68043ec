"""The keyframe getup's latched chain (training/evaluation/artifact_policy.py ChainPolicy): roll → rise → stand,
switched by common/events' hand-over rules, and those rules themselves."""
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from common import events, keyframe_chain
from common import observation as obsdef
from training.evaluation.artifact_policy import ChainPolicy, load_policy

ROOT = Path(__file__).resolve().parents[1]
MEMBER = ROOT / "policies" / "getup_baseline" / "getup_baseline.safetensors"
SPEC = f"chain:{MEMBER},{MEMBER},{MEMBER}"


def _pitched(angle_rad):
    """(w x y z) of a rotation about the world y axis: +90° points the trunk's forward axis down (face down)."""
    return np.array([math.cos(angle_rad / 2), 0.0, math.sin(angle_rad / 2), 0.0], np.float32)


FACE_DOWN, ON_BACK, UPRIGHT = _pitched(math.pi / 2), _pitched(-math.pi / 2), _pitched(0.0)
ON_SIDE = np.array([math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0], np.float32)   # rolled 90° about x


def _state(quat, spin_rad_s=0.0):
    z = np.zeros(obsdef.NUM_JOINTS, np.float32)
    return obsdef.ObservationState(imu_quat=quat, gyro=np.array([spin_rad_s, 0.0, 0.0], np.float32),
                                   command=np.zeros(3, np.float32), q=z, dq=z, default_pose=z, last_action=z,
                                   gait_phase=obsdef.initial_gait_phase(np).astype(np.float32))


def _body(trunk_m, up_z):
    return {"trunk_height": np.float32(trunk_m), "waist_height": np.float32(trunk_m - 0.1), "up_z": np.float32(up_z)}


def test_the_hand_over_rules():
    assert events.forward_z_from_quat(FACE_DOWN) == pytest.approx(-1.0, abs=1e-6)
    assert events.forward_z_from_quat(ON_BACK) == pytest.approx(1.0, abs=1e-6)
    assert events.forward_z_from_quat(UPRIGHT) == pytest.approx(0.0, abs=1e-6)
    low = events.FALLEN_TRUNK_HEIGHT_M - 0.1
    assert events.rolled_face_down(-1.0, low, 0.0)
    assert not events.rolled_face_down(-events.ROLLED_FORWARD_Z + 0.01, low, 0.0)        # not turned far enough
    assert not events.rolled_face_down(-1.0, low, events.ROLLED_MAX_ANG_SPEED_RAD_S)      # still tumbling
    assert not events.rolled_face_down(-1.0, events.FALLEN_TRUNK_HEIGHT_M, 0.0)           # not lying
    assert events.lying_back_or_side(1.0, low, 0.0) and events.lying_back_or_side(0.0, low, 0.0)
    assert not events.lying_back_or_side(-events.FACING_Z - 0.01, low, 0.0)               # face down
    np.testing.assert_array_equal(events.rolled_face_down(np.array([-1.0, 1.0]), low, 0.0), [True, False])


@pytest.mark.parametrize("stage, quat, spin, trunk_m, up_z, want", [
    (ChainPolicy.ROLL, ON_BACK, 0.0, 0.2, 0.0, ChainPolicy.ROLL),       # on the back: roll on
    (ChainPolicy.ROLL, FACE_DOWN, 2.0, 0.2, 0.0, ChainPolicy.ROLL),     # face down but still tumbling
    (ChainPolicy.ROLL, FACE_DOWN, 0.0, 0.2, 0.0, ChainPolicy.RISE),     # rolled: the rise takes over
    (ChainPolicy.RISE, FACE_DOWN, 0.0, 0.2, 0.0, ChainPolicy.RISE),
    (ChainPolicy.RISE, ON_BACK, 0.0, 0.2, 0.0, ChainPolicy.ROLL),       # the rise tipped it onto its back
    (ChainPolicy.RISE, ON_SIDE, 0.0, 0.2, 0.0, ChainPolicy.ROLL),       # ... onto its side
    (ChainPolicy.RISE, UPRIGHT, 0.0, 0.4, 1.0, ChainPolicy.STAND),      # §4.8's gate
    (ChainPolicy.RISE, UPRIGHT, 0.0, 0.4, 0.9, ChainPolicy.RISE),       # tilted: no gate
    (ChainPolicy.STAND, UPRIGHT, 0.0, 0.6, 0.8, ChainPolicy.STAND),     # latched until down
    (ChainPolicy.STAND, FACE_DOWN, 0.0, 0.2, 0.0, ChainPolicy.ROLL),    # down: start over
    (events.KEYFRAME_START, ON_BACK, 0.0, 0.2, 0.0, ChainPolicy.ROLL),  # a fallen start
    (events.KEYFRAME_START, FACE_DOWN, 0.0, 0.2, 0.0, ChainPolicy.RISE),  # ... already face down
    (events.KEYFRAME_START, UPRIGHT, 0.0, 0.45, 0.9, ChainPolicy.RISE),  # a kneeling start
    (events.KEYFRAME_START, UPRIGHT, 0.0, 0.66, 1.0, ChainPolicy.STAND),  # a standing start
])
def test_the_chain_switches_by_the_hand_over_rules(stage, quat, spin, trunk_m, up_z, want):
    chain = load_policy(SPEC)
    assert int(chain.next_stage(np.int32(stage), _state(quat, spin), _body(trunk_m, up_z))) == want


def test_the_acting_member_commands_and_the_idle_ones_read_the_applied_targets():
    chain = load_policy(SPEC)
    assert isinstance(chain, ChainPolicy) and chain.trained and "chain" in chain.describe()
    own, stage = chain.initial_last_action()
    assert own.shape == (3, obsdef.NUM_JOINTS) and stage == events.KEYFRAME_START
    rng = np.random.default_rng(0)
    own = (0.2 * rng.standard_normal(own.shape)).astype(np.float32)
    state = _state(FACE_DOWN)._replace(last_action=(own, np.int32(ChainPolicy.ROLL)))
    (next_own, next_stage), q_target = chain.act(chain.params, state, _body(0.2, 0.0))
    assert int(next_stage) == ChainPolicy.RISE
    member = chain.members[ChainPolicy.RISE]
    a, q = member.act(chain.params[ChainPolicy.RISE], state._replace(last_action=own[ChainPolicy.RISE]), {})
    np.testing.assert_allclose(np.asarray(q_target), np.asarray(q), atol=1e-6)
    np.testing.assert_allclose(np.asarray(next_own)[ChainPolicy.RISE], np.asarray(a), atol=1e-6)
    m = chain.members[ChainPolicy.ROLL].manifest
    idle = np.clip((np.asarray(q_target) - np.asarray(m["default_pose"])) / np.asarray(m["action_scale"]), -1, 1)
    np.testing.assert_allclose(np.asarray(next_own)[ChainPolicy.ROLL], idle, atol=1e-5)


def test_a_chain_may_hand_over_at_a_looser_upright_condition():
    """The rise of a chain loaded with a hand-over up error passes a trunk 1° off upright at the gate's height to
    the stand; §4.8's gate (the default) keeps it in the rise. Only a chain has a hand-over."""
    one_degree = _body(events.KNEEL_GATE_HEIGHT_M, math.cos(math.radians(1.0)))
    rise = np.int32(ChainPolicy.RISE)
    assert int(load_policy(SPEC).next_stage(rise, _state(UPRIGHT), one_degree)) == ChainPolicy.RISE
    assert int(load_policy(SPEC, 0.03).next_stage(rise, _state(UPRIGHT), one_degree)) == ChainPolicy.STAND
    with pytest.raises(ValueError, match="a chain's"):
        load_policy(MEMBER, 0.03)
    with pytest.raises(ValueError, match="in \\(0, 2\\]"):
        load_policy(SPEC, 0.0)


def test_a_bad_chain_spec_is_named():
    with pytest.raises(ValueError, match="ROLL.safetensors,RISE.safetensors,STAND.safetensors"):
        load_policy(f"chain:{MEMBER},{MEMBER}")
    with pytest.raises(ValueError, match="ROLL.safetensors"):
        load_policy(f"chain:{MEMBER},,{MEMBER}")


def test_keyframe_stage_reads_the_same_under_numpy():
    """The one rule for numpy (evaluations) and jax (the chain, the distillation's teacher)."""
    roll, rise, stand = range(len(events.KEYFRAME_STAGES))
    got = events.keyframe_stage(np.array([roll, roll, rise, rise, stand]), np.array([-1.0, 1.0, 1.0, 0.0, 0.0]),
                                np.array([0.2, 0.2, 0.2, 0.4, 0.3]), np.array([0.0, 0.0, 0.0, 1.0, 0.9]),
                                np.zeros(5))
    np.testing.assert_array_equal(got, [rise, roll, roll, stand, roll])
    # a rise 1° off upright at the gate's height: the gate (0.57°) holds it, a looser hand-over passes it on
    tilted = (np.array([rise]), np.array([0.0]), np.array([0.4]), np.array([np.cos(np.radians(1.0))]), np.zeros(1))
    assert events.keyframe_stage(*tilted) == rise
    assert events.keyframe_stage(*tilted, handover_up_error=0.03) == stand


def _chain_folder(folder: Path, handover="kneel_band") -> Path:
    for stage in events.KEYFRAME_STAGES:
        (folder / f"{stage}.safetensors").write_bytes(MEMBER.read_bytes())
    keyframe_chain.write(folder, {s: f"{s}.safetensors" for s in events.KEYFRAME_STAGES}, handover)
    return folder


def test_a_shipped_chain_s_folder_loads_with_its_manifest_s_hand_over(tmp_path):
    chain = load_policy(_chain_folder(tmp_path))
    assert isinstance(chain, ChainPolicy) and chain.handover_up_error == events.KNEEL_BAND_UP_ERROR
    assert [m.path.name for m in chain.members] == [f"{s}.safetensors" for s in events.KEYFRAME_STAGES]
    assert load_policy(tmp_path, events.KNEEL_GATE_UP_ERROR).handover_up_error == events.KNEEL_GATE_UP_ERROR
    assert "0.05" in chain.describe()


@pytest.mark.parametrize("spoil, named", [
    (lambda d: d.pop("handover"), "handover must be one of kneel_gate, kneel_band"),
    (lambda d: d["stages"].pop("rise"), "stages must name exactly roll, rise, stand"),
    (lambda d: d["stages"].update(stand="../stand.safetensors"), "stages.stand must be a file name"),
    (lambda d: d["stages"].update(stand="absent.safetensors"), "stages.stand:"),
    (lambda d: d.update(format="t1-keyframe-chain/0"), "format must be"),
])
def test_a_chain_manifest_that_cannot_run_is_refused_by_what_is_wrong(tmp_path, spoil, named):
    folder = _chain_folder(tmp_path)
    data = json.loads((folder / keyframe_chain.MANIFEST).read_text())
    spoil(data)
    (folder / keyframe_chain.MANIFEST).write_text(json.dumps(data))
    with pytest.raises(keyframe_chain.ChainError, match=re.escape(named)):
        load_policy(folder)


def test_a_folder_that_is_no_chain_is_named_as_a_folder(tmp_path):
    with pytest.raises(ValueError, match="a folder, not a policy artifact"):
        load_policy(tmp_path)


def test_a_chain_below_the_waist_switch_and_an_upright_member_above_it(tmp_path):
    """`CHAIN_FOLDER,UPRIGHT`: the chain acts below the composite's switch, the upright member above; idle, the
    chain's members read the applied targets and its stage goes on by its rule."""
    from training.evaluation.artifact_policy import CompositePolicy
    composite = load_policy(f"{_chain_folder(tmp_path)},{MEMBER}")
    assert isinstance(composite, CompositePolicy) and isinstance(composite.getup, ChainPolicy)
    state = _state(UPRIGHT)._replace(last_action=composite.initial_last_action())
    (chain_carry, _), _ = composite.act(composite.params, state, _body(0.66, 1.0))   # waist 0.56 m: upright acts
    own, stage = chain_carry
    assert int(stage) == ChainPolicy.STAND and np.asarray(own).shape == (3, obsdef.NUM_JOINTS)
