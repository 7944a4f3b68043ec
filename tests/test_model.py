"""Acceptance tests for the T1 model (common/models/t1.xml) and common/model.py."""
import itertools

import mujoco
import numpy as np
import pytest

from common import model as t1
from common import scenarios
from messages import contract

TOTAL_MASS_KG = 31.614357
SOLE_FLAT_TOL_M = 1e-3
KNEEL_HOLD_S = 3.0
KNEEL_MAX_SINK_M = 0.01          # trunk height drift over the hold [m]
KNEEL_MAX_TILT_DEG = 3.0         # trunk up-vector drift [deg]
KNEEL_MAX_SLIDE_M = 0.03         # horizontal trunk drift [m]
KNEEL_GROUND_GEOMS = {"left_thigh", "right_thigh", "left_shank", "right_shank", "left_foot", "right_foot"}


@pytest.fixture(scope="module")
def model():
    m, _ = scenarios.build("flat")
    return m


def _at_key(model, name):
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(name).id)
    mujoco.mj_forward(model, data)
    return data


def test_total_mass(model):
    assert model.body_subtreemass[0] == pytest.approx(TOTAL_MASS_KG, abs=1e-3)
    assert model.nbody == 25  # world + 24 robot bodies


def test_joint_actuator_order_and_limits(model):
    names = [model.joint(i + 1).name for i in range(contract.NUM_JOINTS)]
    assert names == list(contract.JOINT_NAMES)
    assert [model.actuator(i).name for i in range(model.nu)] == list(contract.JOINT_NAMES)
    assert np.all(model.actuator_gear[:, 0] == 1.0)
    lim = t1.torque_limits(model)
    np.testing.assert_array_equal(lim[[0, 2, 10, 11, 12, 14, 15, 16]], [7, 18, 30, 45, 30, 60, 20, 15])
    rng = t1.joint_ranges(model)
    assert rng.shape == (23, 2) and np.all(rng[:, 0] < rng[:, 1])
    np.testing.assert_allclose(rng[14], [0.0, 2.34])
    dofs = slice(6, 29)
    np.testing.assert_allclose(model.dof_armature[dofs], 0.005)
    np.testing.assert_allclose(model.dof_frictionloss[dofs], 0.1)
    np.testing.assert_array_equal(model.dof_damping, 0.0)


def test_gains_and_default_pose(model):
    kp, kd = t1.pd_gains(model)
    assert kp.shape == kd.shape == (23,)
    assert kp[0] == 20 and kd[0] == 0.5 and kp[10] == 100 and kp[14] == 150 and kd[15] == 2
    home = t1.default_pose(model)
    assert home.shape == (23,) and home[3] == pytest.approx(-1.4) and home[14] == pytest.approx(0.4)


def test_sensors_and_sites(model):
    for name in ("gyro", "accelerometer", "orientation", "local_linvel"):
        assert model.sensor(name).dim[0] in (3, 4)
    data = _at_key(model, "home")
    np.testing.assert_allclose(data.site("imu").xpos, data.body("Trunk").xpos)
    np.testing.assert_allclose(data.site("left_foot").xpos, data.body("left_foot_link").xpos)
    assert t1.trunk_height(data) == pytest.approx(0.66585)
    assert t1.waist_height(data) == pytest.approx(0.66585 - 0.1155)


def _box_bottom_corners(model, data, geom):
    centre, rot, half = data.geom_xpos[geom], data.geom_xmat[geom].reshape(3, 3), model.geom_size[geom]
    return np.array([centre + rot @ (half * [sx, sy, -1.0])
                     for sx, sy in itertools.product((-1.0, 1.0), repeat=2)])


def test_home_soles_flat_and_no_self_contact(model):
    data = _at_key(model, "home")
    for foot in ("left_foot", "right_foot"):
        corners = _box_bottom_corners(model, data, model.geom(foot).id)
        np.testing.assert_allclose(corners[:, 2], 0.0, atol=SOLE_FLAT_TOL_M)
    assert t1.self_contacts(model, data) == []
    touching = {model.geom(g).name for g in t1.ground_contacts(model, data)}
    assert touching == {"left_foot", "right_foot"}


def test_zero_pose_and_kneel_no_self_contact(model):
    data = mujoco.MjData(model)
    data.qpos[2] = 0.7
    data.qpos[3] = 1.0
    mujoco.mj_forward(model, data)
    assert t1.self_contacts(model, data) == []
    assert t1.self_contacts(model, _at_key(model, "kneel")) == []


def test_kneel_touches_with_knees_and_toes_only(model):
    data = _at_key(model, "kneel")
    assert t1.lowest_robot_point(model, data) == pytest.approx(0.0, abs=1e-4)
    touching = {model.geom(g).name for g in t1.ground_contacts(model, data)}
    assert {"left_foot", "right_foot"} <= touching and touching <= KNEEL_GROUND_GEOMS
    assert touching & {"left_thigh", "left_shank"} and touching & {"right_thigh", "right_shank"}


def test_kneel_holds_under_shared_pd(model):
    data = _at_key(model, "kneel")
    kp, kd = t1.pd_gains(model)
    lim = t1.torque_limits(model)
    target = t1.kneel_pose(model)
    start = data.xpos[model.body("Trunk").id].copy()
    touched = set()
    for _ in range(int(KNEEL_HOLD_S / model.opt.timestep)):
        data.ctrl[:] = t1.pd_torque(target, data.qpos[7:], data.qvel[6:], kp, kd, lim)
        mujoco.mj_step(model, data)
        touched |= {model.geom(g).name for g in t1.ground_contacts(model, data)}
    end = data.xpos[model.body("Trunk").id]
    assert abs(end[2] - start[2]) < KNEEL_MAX_SINK_M
    assert np.linalg.norm(end[:2] - start[:2]) < KNEEL_MAX_SLIDE_M
    up_z = data.xmat[model.body("Trunk").id].reshape(3, 3)[2, 2]
    assert np.degrees(np.arccos(np.clip(up_z, -1, 1))) < KNEEL_MAX_TILT_DEG
    assert touched <= KNEEL_GROUND_GEOMS, f"unexpected ground contacts {touched - KNEEL_GROUND_GEOMS}"
    assert t1.self_contacts(model, data) == []


def test_spawn_states(model):
    q, v = t1.spawn_state(model, "standing", 0)
    np.testing.assert_array_equal(q[7:], t1.default_pose(model))
    assert q.shape == (30,) and v.shape == (29,) and not v.any()
    q, _ = t1.spawn_state(model, "kneeling", 0)
    np.testing.assert_array_equal(q[7:], t1.kneel_pose(model))
    with pytest.raises(ValueError, match="standing.*kneeling.*fallen"):
        t1.spawn_state(model, "sitting", 0)


def test_unknown_scenario_is_rejected():
    with pytest.raises(ValueError, match="valid: flat"):
        scenarios.build("ice_rink")


def test_fallen_state_deterministic_and_lying(model):
    q1, v1 = t1.fallen_state(model, 3)
    q2, v2 = t1.fallen_state(model, 3)
    np.testing.assert_array_equal(q1, q2)
    np.testing.assert_array_equal(v1, v2)
    q3, _ = t1.fallen_state(model, 4)
    assert not np.allclose(q1, q3)
    q4, _ = t1.spawn_state(model, "fallen", 3)
    np.testing.assert_array_equal(q1, q4)
    data = mujoco.MjData(model)
    for q in (q1, q3):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        assert t1.waist_height(data) < 0.45          # lying, not standing
        assert t1.ground_contacts(model, data)       # on the floor
        rng = t1.joint_ranges(model)
        assert np.all(q[7:] >= rng[:, 0] - 0.05) and np.all(q[7:] <= rng[:, 1] + 0.05)


def test_lying_contacts_fit_mjx_buffers(model):
    """(The model steps in MJX from fallen states: tests/test_cpu_backend.py's MJX/CPU parity.)"""
    data = mujoco.MjData(model)
    for seed in range(12):
        q, v = t1.fallen_state(model, seed)
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_forward(model, data)
        assert 0 < data.ncon <= t1.MJX_NCONMAX, f"seed {seed}: {data.ncon} contacts"
        assert data.nefc <= t1.MJX_NJMAX, f"seed {seed}: {data.nefc} constraint rows"
    for key in ("home", "kneel"):
        data = _at_key(model, key)
        assert data.ncon <= t1.MJX_NCONMAX and data.nefc <= t1.MJX_NJMAX
