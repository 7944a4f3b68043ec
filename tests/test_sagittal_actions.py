"""The sagittal, mirrored action space of the getup env's stage 1 (training/envs/sagittal.py)."""
from __future__ import annotations

import numpy as np
import pytest

from common import model as t1model
from messages.contract import JOINT_NAMES, NUM_JOINTS, joint_index
from training import envs
from training.envs import sagittal


def test_each_pitch_value_drives_both_sides_and_nothing_else():
    m = sagittal.expansion()
    assert m.shape == (NUM_JOINTS, len(sagittal.PITCH_JOINTS))
    full = m @ np.arange(1.0, len(sagittal.PITCH_JOINTS) + 1)
    for j, name in enumerate(sagittal.PITCH_JOINTS):
        if name == "Head_pitch":
            assert full[joint_index(name)] == j + 1
        else:
            assert full[joint_index(f"Left_{name}")] == full[joint_index(f"Right_{name}")] == j + 1
    held = [n for n in JOINT_NAMES if not any(n.endswith(p) for p in sagittal.PITCH_JOINTS)]
    assert held and all(full[joint_index(n)] == 0.0 for n in held)        # roll and yaw keep home


def test_the_kneel_is_in_the_sagittal_space():
    """The kneel keyframe differs from home only in mirrored pitch joints: the reduced policy can reach it."""
    import mujoco
    model = mujoco.MjModel.from_xml_path(str(t1model.MODEL_PATH))
    delta = t1model.kneel_pose(model) - t1model.default_pose(model)
    m = sagittal.expansion()
    reduced = np.linalg.lstsq(m, delta, rcond=None)[0]
    np.testing.assert_allclose(m @ reduced, delta, atol=1e-9)


def test_getup_env_expands_the_policy_action():
    env = envs.make("getup", config_overrides={"stage": "stage1", "fallen.bank_starts": 2,
                                               "action_space": "sagittal"})
    assert env.action_size == len(sagittal.PITCH_JOINTS)
    a = np.linspace(-0.5, 0.5, env.action_size)
    np.testing.assert_allclose(np.asarray(env.full_action(a)), sagittal.expansion() @ a, rtol=1e-6)
    full = envs.make("getup", config_overrides={"stage": "stage1", "fallen.bank_starts": 2})
    assert full.action_size == NUM_JOINTS
    with pytest.raises(ValueError, match="action_space 'mirrored' unknown"):
        envs.make("getup", config_overrides={"stage": "stage1", "fallen.bank_starts": 2, "action_space": "mirrored"})
