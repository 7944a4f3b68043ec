"""Acceptance tests for common/scenarios.py: every scenario builds, walls are where they should be,
puddles really have μ 0.4 (measured by sliding a box), push schedules are seeded."""
import mujoco
import numpy as np
import pytest

from common import model as t1
from common import scenarios as sc

GRAVITY_MPS2 = 9.81
FLOOR_FRICTION = 0.6


@pytest.mark.parametrize("name", sc.SCENARIOS)
def test_each_scenario_builds_and_robot_stands_on_ground(name):
    model, info = sc.build(name, seed=1)
    assert info.name == name and info.seed == 1 and info.description
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    assert len(t1.ground_contacts(model, data)) == 8  # 4 corners per sole: there is ground under it
    assert (model.nq, model.nv, model.nu) == (30, 29, 23)


def test_unknown_scenario_names_the_valid_ones():
    with pytest.raises(ValueError, match="flat.*walls.*puddles.*pushes"):
        sc.build("lava")


def test_walls_positions_and_sizes():
    model, _ = sc.build("walls")
    walls = [model.geom(f"wall_{i}") for i in range(sc.WALL_COUNT)]
    assert len(walls) == 3
    xs = sorted(float(w.pos[0]) for w in walls)
    np.testing.assert_allclose(xs, [2.0, 8.0, 14.0])
    for w in walls:
        assert w.type == mujoco.mjtGeom.mjGEOM_BOX
        np.testing.assert_allclose(2 * w.size, [0.1, 40.0, 0.2])   # thickness x, length y, height z [m]
        np.testing.assert_allclose(w.pos[1:], [0.0, 0.1])          # on the floor, centred on the path
        assert w.bodyid == 0


def _puddle_geoms(model):
    return [model.geom(i) for i in range(model.ngeom) if model.geom(i).name.startswith("puddle_")]


def test_puddle_layout_is_seeded_and_on_the_path():
    a, _ = sc.build("puddles", seed=4)
    b, _ = sc.build("puddles", seed=4)
    c, _ = sc.build("puddles", seed=5)
    pa, pb, pc = _puddle_geoms(a), _puddle_geoms(b), _puddle_geoms(c)
    assert len(pa) == sc.PUDDLE_COUNT
    np.testing.assert_array_equal([g.pos for g in pa], [g.pos for g in pb])
    assert not np.allclose([g.pos for g in pa], [g.pos for g in pc])
    for g in pa:
        sides = 2 * g.size[:2]
        assert np.all((sides >= 0.6) & (sides <= 1.0))
        assert g.pos[0] - g.size[0] >= 1.0 and g.pos[0] + g.size[0] <= 15.0
        assert abs(g.pos[1]) + g.size[1] <= 1.0
        assert g.friction[0] == pytest.approx(0.4) and g.priority > a.geom("floor").priority
        top = g.pos[2] + g.size[2]
        assert 0.0 < top <= 0.001  # a film, not a step


def _slide_deceleration(spec, x, y, v0=1.0, t_measure=0.15):
    """Slide a 2 kg box (0.2 x 0.2 x 0.05 m) at v0 [m/s] along +x from (x, y); mean deceleration [m/s²]."""
    body = spec.worldbody.add_body(name="probe", pos=[x, y, 0.03])
    # the robot file sets inertiafromgeom="false": give the probe its inertia explicitly
    body.explicitinertial = True
    body.ipos = [0.0, 0.0, 0.0]   # MjSpec otherwise leaves the inertial frame at `pos` (measured)
    body.mass = 2.0
    body.inertia = [2.0 / 12 * (0.2**2 + 0.05**2)] * 2 + [2.0 / 12 * (2 * 0.2**2)]
    body.add_freejoint(name="probe_free")
    body.add_geom(name="probe_box", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.025])
    model = spec.compile()
    data = mujoco.MjData(model)
    adr = model.joint("probe_free").qposadr[0]
    dof = model.joint("probe_free").dofadr[0]
    data.qpos[adr:adr + 3] = [x, y, 0.026]
    for _ in range(int(0.2 / model.opt.timestep)):   # let it settle onto the surface
        mujoco.mj_step(model, data)
    data.qvel[dof] = v0
    steps = int(t_measure / model.opt.timestep)
    v_start = data.qvel[dof]
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return (v_start - data.qvel[dof]) / (steps * model.opt.timestep)


def test_puddle_friction_is_really_lower_than_floor():
    spec, _ = sc.build_spec("puddles", seed=2)
    cx, cy = [float(v) for v in sc.puddle_layout(2)[0][:2]]
    on_puddle = _slide_deceleration(spec, cx - 0.15, cy)
    spec_floor, _ = sc.build_spec("puddles", seed=2)
    on_floor = _slide_deceleration(spec_floor, -2.0, 0.0)   # no puddle behind the start
    assert on_puddle == pytest.approx(sc.PUDDLE_FRICTION * GRAVITY_MPS2, rel=0.05)
    assert on_floor == pytest.approx(FLOOR_FRICTION * GRAVITY_MPS2, rel=0.05)


def test_push_schedule_seeded_forward_and_backward():
    _, a = sc.build("pushes", seed=7)
    _, b = sc.build("pushes", seed=7)
    _, c = sc.build("pushes", seed=8)
    assert a.pushes == b.pushes and a.pushes != c.pushes
    assert len(a.pushes) >= 5
    times = [t for t, _ in a.pushes]
    assert times == sorted(times) and times[0] >= 1.0
    xs = np.array([imp for _, imp in a.pushes])
    assert np.all(np.abs(xs[:, 0]) >= 10.0) and np.all(np.abs(xs[:, 0]) <= 25.0)  # firm shove [N·s]
    assert np.all(xs[:, 1:] == 0.0)
    all_x = np.concatenate([[imp[0] for _, imp in info.pushes] for info in (a, c)])
    assert (all_x > 0).any() and (all_x < 0).any()
    _, flat = sc.build("flat", seed=7)
    assert flat.pushes == []


def test_dragged_foot_does_not_trip_on_puddle_edge():
    """A foot-sized box (0.223 x 0.1 x 0.03 m, 0.7 kg) dragged slowly from the floor onto a puddle."""
    spec, _ = sc.build_spec("flat")
    sc.add_puddle(spec, "edge_puddle", 1.0, 0.0, 0.8, 0.8)        # edge at x = 0.6 m
    body = spec.worldbody.add_body(name="foot_probe", pos=[0.4, 0.0, 0.015])
    body.explicitinertial = True
    body.ipos = [0.0, 0.0, 0.0]
    body.mass = 0.7
    body.inertia = [0.0022, 0.0024, 0.0027]
    body.add_freejoint(name="foot_probe_free")
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1115, 0.05, 0.015])
    model = spec.compile()
    data = mujoco.MjData(model)
    adr = model.joint("foot_probe_free").qposadr[0]
    dof = model.joint("foot_probe_free").dofadr[0]
    bid = model.body("foot_probe").id
    drag_n = 0.9 * 0.7 * GRAVITY_MPS2          # above floor friction: it slides
    for _ in range(int(2.0 / model.opt.timestep)):
        data.xfrc_applied[bid, 0] = drag_n if data.qvel[dof] < 0.3 else 0.0
        mujoco.mj_step(model, data)
    assert data.qpos[adr] > 0.8                # crossed the edge (centre was 0.49 m when it met it)
