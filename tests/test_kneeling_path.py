"""Stage 2's reverse curriculum (training/envs/starts/kneeling_path.py): the path's poses and the env's starts."""
import mujoco
import numpy as np
import pytest

from common import model as t1
from training.envs.starts import kneeling_path

HALF_KNEEL_RAD = (-1.5, 2.2, -0.7)      # left hip pitch, knee, ankle pitch at progress 1
HALF_KNEEL_HOLD_S = 3.0
HALF_KNEEL_MAX_SINK_M = 0.05     # measured 0.03 m
HALF_KNEEL_MIN_UP_Z = 0.95       # measured ≥ 0.97
KNEEL_SWING_MAX_LIFT_M = 0.01    # the right knee stays on the floor while the left leg swings (measured 6 mm)


@pytest.fixture(scope="module")
def model():
    return t1.load_model()


@pytest.fixture(scope="module")
def waypoints():
    from training.envs.getup_stand import default_config
    return default_config().reverse_curriculum.left_leg_waypoints


@pytest.fixture(scope="module")
def bank(model, waypoints):
    """41 starts: index 20 is progress 1 (the half kneel), 40 the kneel."""
    return kneeling_path.path_bank(model, t1.keyframe_qpos(model, "home"), t1.keyframe_qpos(model, "kneel"),
                                waypoints, 41)


def test_path_runs_from_standing_to_the_kneel(model, bank):
    home, kneel = t1.keyframe_qpos(model, "home"), t1.keyframe_qpos(model, "kneel")
    assert np.allclose(bank[-1], kneel, atol=1e-4)
    assert np.allclose(bank[0][7:], home[7:]) and bank[0][2] == pytest.approx(home[2], abs=0.005)
    # the midpoint is the half kneel: left leg as given, right leg as the kneel
    half = bank[20]
    for name, angle in zip(kneeling_path.LEFT_LEG, HALF_KNEEL_RAD):
        assert half[model.joint(name).qposadr[0]] == pytest.approx(angle)
    right = [model.joint(n).qposadr[0] for n in ("Right_Hip_Pitch", "Right_Knee_Pitch", "Right_Ankle_Pitch")]
    assert np.allclose(half[right], kneel[right])


def test_the_left_leg_swings_back_with_the_right_knee_on_the_floor(model, bank):
    kneel_z = t1.keyframe_qpos(model, "kneel")[2]
    assert np.all(bank[20:, 2] - kneel_z < KNEEL_SWING_MAX_LIFT_M)


def test_every_start_rests_on_the_floor_upright_without_self_contact(model, bank):
    data = mujoco.MjData(model)
    for q in bank:
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        assert t1.lowest_robot_point(model, data) == pytest.approx(0.0, abs=1e-6)
        assert np.allclose(q[3:7], (1, 0, 0, 0)) and np.allclose(q[0:2], 0)
        assert t1.self_contacts(model, data) == []


def test_half_kneel_holds_under_shared_pd_on_its_left_foot(model, bank):
    data = mujoco.MjData(model)
    data.qpos[:] = bank[20]
    kp, kd = t1.pd_gains(model)
    lim = t1.torque_limits(model)
    target = bank[20][7:].copy()
    touched = set()
    for _ in range(int(HALF_KNEEL_HOLD_S / model.opt.timestep)):
        data.ctrl[:] = t1.pd_torque(target, data.qpos[7:], data.qvel[6:], kp, kd, lim)
        mujoco.mj_step(model, data)
        touched |= {model.geom(g).name for g in t1.ground_contacts(model, data)}
    assert bank[20][2] - data.qpos[2] < HALF_KNEEL_MAX_SINK_M
    assert data.xmat[model.body("Trunk").id].reshape(3, 3)[2, 2] >= HALF_KNEEL_MIN_UP_Z
    assert "left_foot" in touched


def test_progress_and_bank_limits():
    assert kneeling_path.bank_range(0.0, 2.0, 41) == slice(0, 41)
    assert kneeling_path.bank_range(0.0, 1.0, 41) == slice(0, 21)
    assert kneeling_path.bank_range(0.0, 0.05, 41) == slice(0, 2)
    assert kneeling_path.bank_range(1.0, 2.0, 41) == slice(20, 41)      # the swing, half kneel included
    assert kneeling_path.bank_range(1.01, 1.1, 41) == slice(21, 23)
    for lo, hi in ((0.0, 0.0), (0.0, -1.0), (0.0, 2.5), (1.5, 1.0), (-0.1, 1.0)):
        with pytest.raises(ValueError, match="max_progress"):
            kneeling_path.bank_range(lo, hi, 41)
    with pytest.raises(ValueError, match="progress"):
        kneeling_path.pose_at([(0.0, np.zeros(3)), (2.0, np.ones(3))], 2.1)
    assert np.allclose(kneeling_path.pose_at([(0.0, np.zeros(3)), (0.5, np.ones(3)), (2.0, np.zeros(3))], 1.25), 0.5)
    with pytest.raises(ValueError, match="bank_size"):
        kneeling_path.path_bank(None, None, None, [], 1)


def test_bad_waypoints_are_refused(model):
    home, kneel = t1.keyframe_qpos(model, "home"), t1.keyframe_qpos(model, "kneel")
    for bad in ([[1.0, -1.5, 2.2]], [[1.2, -1.5, 2.2, -0.7], [1.1, -1.4, 2.3, -0.8]], [[2.0, 0.0, 1.9, 0.0]]):
        with pytest.raises(ValueError, match="left_leg_waypoints"):
            kneeling_path.path_points(model, home, kneel, bad)


def test_the_stand_task_draws_starts_up_to_max_progress_and_at_the_kneel():
    import jax

    from training import envs
    cfg = envs.default_config("getup_stand")
    cfg.backend = "cpu"
    cfg.reverse_curriculum.max_progress = 1.0
    env = envs.make("getup_stand", config=cfg)
    qpos, _, kind, _ = jax.vmap(env._start_state)(jax.random.split(jax.random.PRNGKey(0), 2000))
    qpos, kind = np.asarray(qpos), np.asarray(kind)
    at_kneel = kind == 1
    assert abs(at_kneel.mean() - cfg.reverse_curriculum.kneel_prob) < 0.04
    assert np.allclose(qpos[at_kneel], np.asarray(env._kneel_qpos), atol=1e-5)
    # progress ≤ 1: standing … half kneel, never the leg swing of p ∈ (1, 2) (left knee 2.2 rad at most)
    left_knee = qpos[~at_kneel, env.mj_model.joint("Left_Knee_Pitch").qposadr[0]]
    assert left_knee.max() <= HALF_KNEEL_RAD[1] + 1e-5 and len(np.unique(np.round(left_knee, 4))) == 21
    cfg.reverse_curriculum.min_progress, cfg.reverse_curriculum.max_progress = 1.0, 2.0   # the swing only
    swing = envs.make("getup_stand", config=cfg)
    bank = kneeling_path.path_bank(env.mj_model, np.asarray(env._home_qpos), np.asarray(env._kneel_qpos),
                                cfg.reverse_curriculum.left_leg_waypoints, cfg.reverse_curriculum.bank_size)
    assert np.allclose(np.asarray(swing._path_bank), bank[20:], atol=1e-6)    # half kneel (p 1) … kneel
    cfg.reverse_curriculum.min_progress = 0.0
    cfg.reverse_curriculum.max_progress = 0.0      # off: the seed's start, every episode at the kneel
    env = envs.make("getup_stand", config=cfg)
    _, _, kind, _ = jax.vmap(env._start_state)(jax.random.split(jax.random.PRNGKey(0), 64))
    assert np.all(np.asarray(kind) == 1)


def test_bad_curriculum_config_is_refused():
    from training import envs
    cfg = envs.default_config("getup_stand")
    cfg.backend = "cpu"
    cfg.reverse_curriculum.kneel_prob = 1.5
    with pytest.raises(ValueError, match="kneel_prob"):
        envs.make("getup_stand", config=cfg)


def test_cpu_backend_resets_a_batch_whose_start_velocity_is_shared():
    """The path starts share one zero qvel; the CPU backend's reset callback must broadcast it (vmap)."""
    import jax

    from training import envs
    cfg = envs.default_config("getup_stand")
    cfg.backend = "cpu"
    cfg.reverse_curriculum.max_progress = 2.0
    env = envs.make("getup_stand", config=cfg)
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 8))
    assert state.data.qpos.shape == (8, env.mj_model.nq)
    assert np.all(np.asarray(state.info["trunk_height"]) > 0.35)


def test_render_strip_draws_one_frame_per_start(tmp_path):
    import PIL.Image
    kneeling_path.render_strip(str(tmp_path / "path.png"), size=3, px=64)
    assert PIL.Image.open(tmp_path / "path.png").size == (3 * 64, 64)
