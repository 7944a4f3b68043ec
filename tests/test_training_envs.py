"""MJX training envs (training/envs): API, contact budget, PD law vs the firmware, and (slow) jit+vmap
rollouts of every task with the observation checked against common/observation.py.

Fast tests never jit an env step (eval_shape only); each slow test compiles one env's reset+step: MJX for the
getup env (a minute or two on a shared 2-core CPU), the CPU backend for the joystick and baseline envs (MJX's
joystick step is compiled by tests/test_cpu_backend.py's parity test)."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from common import model as t1model
from common import observation as obsdef
from training import envs
from training.envs import collision, motor

OBS_SIZES = {  # actor size from the terms; critic = actor + base extras + task extras
    "joystick": (82, 82 + 37 + 2 + 6),
    "getup": (52, 52 + 37 + 2),
    "getup_kneel": (52, 52 + 37 + 2),
    "getup_roll": (52, 52 + 37 + 2),
    "getup_stand": (52, 52 + 37 + 2),
    "getup_baseline": (52, 52 + 37 + 2),
    "unified": (82, 82 + 37 + 6),
}
SMALL = {"episode_length": 20}
GETUP_SMALL = {"episode_length": 20, "fallen.bank_starts": 2}


def _make(task, **extra):
    # tasks with fallen starts get a 2-state bank: precomputing the default 128 takes minutes
    over = dict(GETUP_SMALL if "fallen" in envs.default_config(task) else SMALL)
    over.update(extra)
    return envs.make(task, config_overrides=over)


@pytest.fixture(scope="module")
def env_by_task():
    return {t: _make(t) for t in envs.TASKS}


# ------------------------------------------------------------------ API / config
def test_tasks_and_configs():
    assert envs.TASKS == ("joystick", "getup", "getup_kneel", "getup_roll", "getup_stand", "getup_baseline", "unified")
    for task in envs.TASKS:
        cfg = envs.default_config(task)
        assert cfg.ctrl_dt == pytest.approx(0.02) and cfg.sim_dt == pytest.approx(0.002)
        assert cfg.impl == "jax" and cfg.episode_length > 0
    # the keyframe curriculum's three tasks as the seed runs them (§4.5): fallen → kneel, kneel → stand, the full
    # task's mixed starts; no energy term, no observation noise until the fine-tunes
    for task, probs in (("getup_kneel", [1.0, 0.0, 0.0]), ("getup_stand", [0.0, 1.0, 0.0]),
                        ("getup", [0.4, 0.4, 0.2]), ("getup_baseline", [1.0, 0.0, 0.0])):
        cfg = envs.default_config(task)
        assert list(cfg.start_probs) == probs and cfg.reward.scales.energy == 0.0 and cfg.obs_noise_scale == 0.0
        assert cfg.action_space == "full" and cfg.collision == "full_body", task
    assert envs.default_config("getup_kneel").reward.scales.to_dict() == {
        "height": 1.0, "pose": 1.0, "gate": 0.0, "upright": 0.0, "energy": 0.0}   # the seed's stage 1
    uni, joy = envs.default_config("unified"), envs.default_config("joystick")
    assert list(uni.start_probs) == [0.4, 0.4, 0.2] and uni.collision == "full_body"
    assert uni.episode_length == 1000 and uni.command_resample_steps == 500 and uni.zero_command_prob == 0.1
    assert uni.push.to_dict() == joy.push.to_dict() and uni.command_ranges.to_dict() == joy.command_ranges.to_dict()
    with pytest.raises(ValueError, match="unknown task"):
        envs.make("dance")
    with pytest.raises((KeyError, AttributeError)):
        envs.make("joystick", config_overrides={"no_such_knob": 1})


def test_observation_sizes_and_manifest(env_by_task):
    for task, env in env_by_task.items():
        n_actor, n_critic = OBS_SIZES[task]
        assert env.observation_size == {"state": (n_actor,), "privileged_state": (n_critic,)}, task
        assert env.action_size == 23
        assert obsdef.observation_size(env.obs_terms) == n_actor
        m = env.manifest_fields()
        assert m["obs_terms"] == [list(t) for t in env.obs_terms]
        kp, kd = t1model.pd_gains(t1model.load_model())
        np.testing.assert_allclose(m["kp"], kp)
        np.testing.assert_allclose(m["kd"], kd)
        assert m["control_dt"] == pytest.approx(0.02) and len(m["default_pose"]) == 23
        assert set(m["command_ranges"]) == {"vx", "vy", "yaw_rate"}
    assert env_by_task["joystick"].obs_terms == list(obsdef.TERMS_UNION)
    assert env_by_task["getup"].obs_terms == list(obsdef.TERMS_GETUP)
    assert env_by_task["unified"].obs_terms == list(obsdef.TERMS_UNION)
    # one gain set and one default pose for all three policies (and the student's env); two action maps:
    # the joystick's ±0.5 rad, and the getup expert's wider one, which the student shares (distill/teacher.py
    # converts the joystick expert's actions into it)
    fields = {task: env.manifest_fields() for task, env in env_by_task.items()}
    for key in ("kp", "kd", "default_pose", "control_dt"):
        assert all(f[key] == fields["joystick"][key] for f in fields.values()), key
    assert fields["joystick"]["action_scale"] == 0.5
    assert fields["unified"]["action_scale"] == fields["getup"]["action_scale"]


def test_step_pytree_is_stable(env_by_task):
    """step's output has reset's exact structure, shapes, dtypes and weak types: no jit retrace."""

    def spec(x):
        return x.shape, str(x.dtype), bool(getattr(x, "weak_type", False))

    for task, env in env_by_task.items():
        s0 = jax.eval_shape(env.reset, jax.random.PRNGKey(0))
        s1 = jax.eval_shape(env.step, s0, jax.ShapeDtypeStruct((23,), jnp.float32))
        a, b = jax.tree_util.tree_flatten(s0), jax.tree_util.tree_flatten(s1)
        assert a[1] == b[1], task
        assert [spec(x) for x in a[0]] == [spec(x) for x in b[0]], task
        for key in ("trunk_height", "waist_height", "up_z"):
            assert s0.info[key].shape == (), (task, key)


# ------------------------------------------------------------------ contacts
def test_contact_budget_fits_model_py_sizes():
    for variant in collision.VARIANTS:
        budget = collision.contact_budget(collision.build_model(variant))
        assert budget["contacts"] <= t1model.MJX_NCONMAX, variant
        assert budget["constraint_rows"] <= t1model.MJX_NJMAX, variant
    feet = collision.build_model("feet_only")
    colliding = [feet.geom(g).name for g in range(feet.ngeom) if feet.geom_contype[g] or feet.geom_conaffinity[g]]
    assert sorted(colliding) == sorted(["floor", *collision.FOOT_GEOMS])


def test_full_body_keeps_every_reachable_pair():
    """Pairs excluded by the full-body variant never come within 3 cm in fresh random poses."""
    full = collision.build_model("full_body")
    kept = collision._candidate_body_pairs(full)
    extra = collision._sample_contact_bodies(t1model.load_model(), 500, 0.0, seed=12345)
    assert extra <= set(collision.reachable_body_pairs())
    assert extra <= kept


def test_full_body_matches_hil_model_on_fallen_states():
    """Every contact the HIL model finds in fallen / kneel / home states is also a slot in the MJX variant."""
    full, base = collision.build_model("full_body"), t1model.load_model()
    pairs_full = collision._candidate_body_pairs(full) | {("floor",)}
    d = __import__("mujoco").MjData(base)
    qpos, _ = envs.fallen_states(4, 0)
    for q in [*qpos, t1model.keyframe_qpos(base, "kneel"), t1model.keyframe_qpos(base, "home")]:
        d.qpos[:] = q
        __import__("mujoco").mj_forward(base, d)
        for a, b in t1model.self_contacts(base, d):
            ba = base.body(base.geom_bodyid[base.geom(a).id]).name
            bb = base.body(base.geom_bodyid[base.geom(b).id]).name
            assert tuple(sorted((ba, bb))) in pairs_full


# ------------------------------------------------------------------ PD law vs firmware
def test_motor_constants_match_firmware():
    fw = pytest.importorskip("sim_hil.firmware")
    np.testing.assert_allclose(motor.D_SAFE_NMS, fw.D_SAFE, atol=1e-6)
    m = t1model.load_model()
    np.testing.assert_allclose(t1model.torque_limits(m), fw.TORQUE_LIMIT, atol=1e-6)
    np.testing.assert_allclose(t1model.joint_ranges(m)[:, 0], fw.Q_MIN, atol=1e-6)
    np.testing.assert_allclose(t1model.joint_ranges(m)[:, 1], fw.Q_MAX, atol=1e-6)


def test_env_pd_torque_equals_firmware_motor_step(env_by_task):
    fw = pytest.importorskip("sim_hil.firmware")
    env = env_by_task["joystick"]
    rng = np.random.default_rng(7)
    lo, hi = fw.Q_MIN, fw.Q_MAX
    motors = fw.MotorArray()
    now_us = 0
    for case in range(20):
        q_des = rng.uniform(lo, hi)
        q = rng.uniform(lo - 0.15, hi + 0.15)   # includes soft-stop territory beyond the ranges
        dq = rng.uniform(-8, 8, 23)
        kp, kd = env.manifest_fields()["kp"], env.manifest_fields()["kd"]
        frames = fw.pack_commands(q_des, np.zeros(23), kp, kd, np.zeros(23))
        q_des_w, dq_des_w, kp_w, kd_w, tau_ff_w = fw.unpack_command(frames)  # what the motor received
        now_us += 2000
        assert motors.receive_all(frames, now_us) == 0
        tau_fw = motors.step(q, dq, now_us)
        # The env applies dq_des = 0 and tau_ff = 0 exactly; the wire's symmetric ranges carry them as
        # ±half a step, so for a like-for-like comparison they are folded into q_des (kp > 0 here).
        q_des_eff = q_des_w + (kd_w * dq_des_w + tau_ff_w) / kp_w
        tau_env = np.asarray(motor.motor_torque(jnp.asarray(q_des_eff), jnp.asarray(q), jnp.asarray(dq),
                                                jnp.asarray(kp_w), jnp.asarray(kd_w), env._tau_limit,
                                                env._q_min, env._q_max, env._d_safe))
        unclamped = np.abs(tau_fw) < fw.TORQUE_LIMIT - 1e-3
        np.testing.assert_allclose(tau_env, tau_fw, atol=2e-3 + 1e-5 * np.abs(tau_fw).max(), err_msg=f"case {case}")
        # and the env's own gains (biasprm slots) give the same law with the unquantised command
        tau_direct = np.asarray(env.pd_torque(jnp.asarray(q_des), jnp.asarray(q), jnp.asarray(dq)))
        step_tol = (fw.KP_MAX / 4095) * np.abs(q_des - q) + (fw.KD_MAX / 4095) * np.abs(dq) \
            + 2 * fw.Q_MAX_RAD / 65535 * np.asarray(kp) \
            + fw.V_RANGE / 4095 * np.asarray(kd) + fw.T_RANGE / 4095 + 1e-3  # one wire step per field
        assert np.all(np.abs(tau_direct - tau_fw)[unclamped] <= step_tol[unclamped]), f"case {case}"


# ------------------------------------------------------------------ fallen starts
def test_fallen_states_seeded_and_cached():
    q1, v1 = envs.fallen_states(3, 5)
    q2, v2 = envs.fallen_states(2, 6)
    assert q1.shape == (3, 30) and v1.shape == (3, 29)
    np.testing.assert_array_equal(q1[1:], q2)
    np.testing.assert_array_equal(v1[1:], v2)
    assert np.all(q1[:, 2] < 0.4)  # lying: the trunk is low
    with pytest.raises(ValueError, match="num"):
        envs.fallen_states(0, 0)


def test_domain_randomize_shapes(env_by_task):
    env = env_by_task["joystick"]
    model, in_axes = envs.domain_randomize(env.mjx_model, jax.random.split(jax.random.PRNGKey(0), 4))
    assert model.actuator_biasprm.shape == (4, 23, 10) and in_axes.actuator_biasprm == 0
    kp = np.asarray(model.actuator_biasprm[:, :, 0]) / np.asarray(env.manifest_fields()["kp"])
    assert np.all((kp >= 0.9) & (kp <= 1.1)) and kp.std() > 0
    assert model.geom_friction.shape[0] == 4 and in_axes.body_pos is None


# ------------------------------------------------------------------ rollouts (slow: one compile each)
def _observation_reference(env, state, command, phase):
    """The IMU terms come from the model's sensors (as in HIL: after mj_step, sensordata holds the
    readings of the substep's start), the joint terms from qpos / qvel."""
    d = state.data
    (g_adr, _), (q_adr, _) = env._sensor["gyro"], env._sensor["orientation"]
    s = obsdef.ObservationState(
        imu_quat=np.asarray(d.sensordata[..., q_adr:q_adr + 4]), gyro=np.asarray(d.sensordata[..., g_adr:g_adr + 3]),
        command=np.asarray(command), q=np.asarray(d.qpos[..., 7:]), dq=np.asarray(d.qvel[..., 6:]),
        default_pose=np.asarray(env._default_pose_np), last_action=np.asarray(state.info["last_act"]),
        gait_phase=np.asarray(phase))
    return obsdef.build_observation(env.obs_terms, s)


def _rollout(task, steps=3, batch=2, **over):
    env = _make(task, **{"noise.level": 0.0, **over})
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(1), batch))
    states = [state]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        state = step(state, jnp.asarray(rng.uniform(-0.2, 0.2, (batch, 23)), jnp.float32))
        states.append(state)
    return env, states


def _check_common(env, states, batch=2):
    n_actor, n_critic = env.observation_size["state"][0], env.observation_size["privileged_state"][0]
    for s in states:
        assert s.obs["state"].shape == (batch, n_actor) and s.obs["privileged_state"].shape == (batch, n_critic)
        for leaf in jax.tree_util.tree_leaves((s.obs, s.reward, s.metrics)):
            assert np.all(np.isfinite(np.asarray(leaf)))
        for key in ("trunk_height", "waist_height", "up_z"):
            assert s.info[key].shape == (batch,)
        np.testing.assert_allclose(s.info["trunk_height"], s.data.xpos[:, env._trunk_id, 2], atol=1e-6)


@pytest.mark.slow
def test_joystick_rollout():
    # on the CPU backend (MJX's joystick step: tests/test_cpu_backend.py's parity test, which compiles it anyway)
    env, states = _rollout("joystick", **{"zero_command_prob": 1.0, "push.enable": False, "backend": "cpu"})
    _check_common(env, states)
    for s in states:
        ref = _observation_reference(env, s, s.info["command"], s.info["phase"])
        np.testing.assert_allclose(np.asarray(s.obs["state"]), ref, atol=1e-5)
        # zero command: the gait clock stays frozen at its initial value
        np.testing.assert_allclose(np.asarray(s.info["phase"]), np.broadcast_to(obsdef.initial_gait_phase(), (2, 2)))
    rewards = set(k for k in states[-1].metrics if k.startswith("reward/"))
    assert rewards >= {"reward/tracking_lin_vel", "reward/feet_phase"}
    assert float(states[-1].info["up_z"].min()) > 0.9  # three ticks from home: still upright


@pytest.mark.parametrize("task", ["getup", "getup_kneel", "getup_stand", "getup_baseline"])
def test_getup_rollout(task):
    # on the CPU backend (MJX's getup step: tests/test_cpu_backend.py's evaluation parity test)
    env, states = _rollout(task, batch=3, backend="cpu")
    _check_common(env, states, batch=3)
    zeros3, phase0 = np.zeros((3, 3)), np.broadcast_to(obsdef.initial_gait_phase(), (3, 2))
    for s in states:
        np.testing.assert_allclose(np.asarray(s.obs["state"]), _observation_reference(env, s, zeros3, phase0),
                                   atol=1e-5)
        # every task logs its scaled terms and the same bookkeeping
        assert set(s.metrics) == {*(f"reward/{k}" for k in env.config.reward.scales), "failed_rises", "gate",
                                  "gate_reached", "success", "success_from_kneel", "success_from_fallen"}
        # every task counts the successes of fallen-start episodes apart (the evaluation's aim)
        np.testing.assert_array_equal(np.asarray(s.metrics["success_from_fallen"]),
                                      np.asarray(s.metrics["success"]) * (np.asarray(s.info["start_kind"]) == 0))


def test_unified_knockdown_pushes(env_by_task):
    """knockdown.prob of the unified env's pushes are as hard as the loop's push test; the rest (all, by
    default) are the joystick env's."""
    keys = jax.random.split(jax.random.PRNGKey(3), 4000)
    walk_lo, walk_hi = envs.default_config("joystick").push.magnitude_range_mps
    default = np.asarray(jax.vmap(env_by_task["unified"]._push_magnitude)(keys))
    assert default.min() >= walk_lo and default.max() <= walk_hi
    env = _make("unified", **{"knockdown.prob": 0.25})
    lo, hi = env._config.knockdown.magnitude_range_mps
    mixed = np.asarray(jax.vmap(env._push_magnitude)(keys))
    hard = mixed > walk_hi
    assert np.all((mixed >= walk_lo) & (mixed <= hi)) and np.all(mixed[hard] >= lo)
    assert 0.22 < hard.mean() < 0.28       # 1000 ± 27 (1 σ) of 4000 draws
    for bad in ({"knockdown.prob": 1.5}, {"knockdown.magnitude_range_mps": [1.6, 1.0]}):
        with pytest.raises(ValueError, match="knockdown"):
            _make("unified", **bad)
