"""The CPU physics backend (training/envs/cpu_backend.py): the firmware motor law as MuJoCo's control
callback, and parity with the MJX backend over one control step.

Parity tolerances (standing start, the same action): both engines run the same model, motor law and
env code, but MJX computes in float32 and its solver is a port, not the C code, so velocities after ten
2 ms substeps differ by float32 rounding amplified through contact (measured ≤ 7e-4 rad/s; bound 5e-3);
positions, orientation and the reward terms by far less. A start that hits the floor hard (random joint
scales) makes both engines chaotic within one step: parity is asserted where the physics is not."""
from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from common import model as t1model
from messages import contract
from training import envs

VEL_TOL = 5e-3        # [rad/s] joint velocity / gyro terms of the observation
OBS_TOL = 1e-4        # every other observation entry (gravity, joint offsets, command, phase)
REWARD_REL_TOL = 1e-2
REWARD_ABS_TOL = 1e-4
OPEN_SUPERVISOR = (1e6, 1e6)   # (max target step [rad], range fraction): neither limits anything


def _standing_cfg(backend):
    cfg = envs.default_config("joystick")
    cfg.backend = backend
    cfg.noise.level = 0.0
    cfg.push.enable = False
    cfg.reset.update(xy_range_m=0.0, yaw_range_rad=0.0, joint_scale=[1.0, 1.0], root_vel_range=0.0)
    return cfg


@pytest.fixture(scope="module")
def cpu_env():
    return envs.make("joystick", config=_standing_cfg("cpu"))


def test_motor_callback_equals_firmware_motor_step(cpu_env):
    fw = pytest.importorskip("sim_hil.firmware")
    mj = cpu_env.mj_model
    d = mujoco.MjData(mj)
    rng = np.random.default_rng(11)
    motors = fw.MotorArray()
    kp, kd = np.asarray(cpu_env.manifest_fields()["kp"]), np.asarray(cpu_env.manifest_fields()["kd"])
    tau_limit = np.asarray(cpu_env._tau_limit)
    for case in range(20):
        q = rng.uniform(fw.Q_MIN - 0.15, fw.Q_MAX + 0.15)      # soft-stop territory included
        dq = rng.uniform(-8, 8, 23)
        # a target the supervisor passes unchanged (within its torque reach; rate and range opened below),
        # so that the torques compare the firmware law alone (tests/test_training_motor.py: the supervisor)
        q_des = q + (kd * dq + rng.uniform(-0.9, 0.9, 23) * tau_limit) / kp
        frames = fw.pack_commands(q_des, np.zeros(23), kp, kd, np.zeros(23))
        q_des_w, dq_des_w, kp_w, kd_w, tau_ff_w = fw.unpack_command(frames)
        assert motors.receive_all(frames, 2000 * (case + 1)) == 0
        tau_fw = motors.step(q, dq, 2000 * (case + 1))
        # the callback sends dq_des = tau_ff = 0 exactly; fold the wire's half-steps into q_des
        m = mj.__copy__()
        m.actuator_biasprm[:, 0], m.actuator_biasprm[:, 1] = kp_w, kd_w
        d.qpos[7:], d.qvel[6:] = q, dq
        d.userdata[:23] = d.userdata[23:46] = q_des_w + (kd_w * dq_des_w + tau_ff_w) / kp_w
        d.userdata[46:48] = OPEN_SUPERVISOR           # no rate or range limit
        d.userdata[48] = cpu_env._cpu._lib.t1_mjcb_marker()
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(d.ctrl, tau_fw, atol=1e-3, err_msg=f"case {case}")
        np.testing.assert_allclose(d.actuator_force, tau_fw, atol=1e-3, err_msg=f"case {case}")


def test_motor_callback_leaves_other_models_alone(cpu_env):
    mj = t1model.load_model()                 # the HIL simulator's model: no backend userdata
    d = mujoco.MjData(mj)
    d.ctrl[:] = 5.0
    mujoco.mj_forward(mj, d)
    assert np.all(d.ctrl == 5.0)


def test_batch_of_envs_stands_under_the_home_targets(cpu_env):
    n = 4
    reset, step = jax.jit(jax.vmap(cpu_env.reset)), jax.jit(jax.vmap(cpu_env.step))
    state = reset(jax.random.split(jax.random.PRNGKey(0), n))
    for _ in range(25):                       # 0.5 s with action 0: q_des = home
        state = step(state, jnp.zeros((n, 23)))
    trunk = np.asarray(state.info["trunk_height"])
    assert np.all(np.abs(trunk - contract.NOMINAL_STANDING_TRUNK_HEIGHT_M) < 0.02), trunk
    assert not np.any(np.asarray(state.done))
    assert np.all(np.asarray(cpu_env.foot_contacts(jax.tree.map(lambda x: x[0], state.data))))


@pytest.mark.slow
def test_one_control_step_matches_the_mjx_backend(cpu_env):
    mjx_env = envs.make("joystick", config=_standing_cfg("mjx"))
    action = jax.random.uniform(jax.random.PRNGKey(4), (23,), minval=-0.2, maxval=0.2)
    after, jump = {}, {}
    for name, env in (("mjx", mjx_env), ("cpu", cpu_env)):
        s0, step = jax.jit(env.reset)(jax.random.PRNGKey(3)), jax.jit(env.step)
        after[name] = (s0, step(s0, action))
        # a full-scale action: the supervisor's target moves at the runtime's rate on both backends
        # (10 ticks × the target step at most; tests/test_training_motor.py checks the rule itself)
        jump[name] = np.asarray(step(s0, jnp.ones(23)).info["runtime_target"]) - np.asarray(s0.info["runtime_target"])
    cap = mjx_env.n_substeps * mjx_env._target_step
    for name in ("mjx", "cpu"):
        assert cap + 1e-5 >= np.abs(jump[name]).max() > 0.5 * cap, name
    capped = np.abs(jump["cpu"]) > cap - 1e-5
    np.testing.assert_array_equal(np.abs(jump["mjx"]) > cap - 1e-5, capped)
    # the joints under the cap follow R6's torque reach, which reads q and dq: the backends' float32 and float64
    # dynamics of a full-scale step part by up to ~0.015 rad there
    np.testing.assert_allclose(jump["mjx"][~capped], jump["cpu"][~capped], atol=0.03)
    terms = dict(mjx_env.obs_terms)
    vel = np.zeros(sum(terms.values()), bool)
    start = 0
    for name, size in mjx_env.obs_terms:
        vel[start:start + size] = name in ("gyro", "joint_vel")
        start += size
    for i in (0, 1):                          # after reset, after one control step
        a, b = (np.asarray(after[k][i].obs["state"]) for k in ("mjx", "cpu"))
        np.testing.assert_allclose(a[vel], b[vel], atol=VEL_TOL, err_msg=f"velocity terms, state {i}")
        np.testing.assert_allclose(a[~vel], b[~vel], atol=OBS_TOL, err_msg=f"other terms, state {i}")
    m, c = after["mjx"][1], after["cpu"][1]
    for key in m.metrics:
        np.testing.assert_allclose(float(c.metrics[key]), float(m.metrics[key]), rtol=REWARD_REL_TOL,
                                   atol=REWARD_ABS_TOL, err_msg=key)
    np.testing.assert_allclose(float(c.reward), float(m.reward), rtol=REWARD_REL_TOL, atol=REWARD_ABS_TOL)
    assert float(c.done) == float(m.done) == 0.0


@pytest.mark.parametrize("task", envs.TASKS)
def test_every_task_step_keeps_the_metrics_wrappers_add(task):
    """brax's EvalWrapper puts "reward" into state.metrics and scans over step: a step that returns a
    fresh metrics dict breaks every PPO run with evaluations (the CPU backend makes this check cheap)."""
    over = {"backend": "cpu", "episode_length": 20}
    if "fallen" in envs.default_config(task):
        over["fallen.bank_starts"] = 2
    env = envs.make(task, config_overrides=over)
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    state.metrics["reward"] = jnp.zeros(())
    after = jax.jit(env.step)(state, jnp.zeros(23))
    assert set(after.metrics) == set(state.metrics)


# Getup evaluation rollouts (training/evaluation/batch.py's MJX scan, training/evaluation/cpu.py's C batch), first
# control tick from the same fallen starts and policy. The supervisor's rate limit keeps the torques off
# their clamps, so they follow the engines' small differences in q, dq (kp·Δq): trunk readings agree to
# ≤ 1e-3 (measured 3.4e-4) and peak torques to ≤ 0.5 N·m of 60 (measured 0.13); integrals (energy, Σ|q̈|·dt,
# Σ|τ|·dt) to ≤ 3 % (measured ≤ 2.5 %: the engines' contact solvers differ on impact); the peaks of q̈ and one
# substep's energy, and the contact forces, are single-substep impact values, where the two solvers differ most
# (measured ≤ 13 % and ≤ 10 %).
EVAL_TOL = {"readings": (0.0, 1e-3), "max_torque_Nm": (0.0, 0.5), "energy_J": (0.03, 1e-3),
            "qacc_integral": (0.03, 1e-3), "torque_integral": (0.03, 1e-3), "max_qacc": (0.2, 1.0),
            "max_energy_J": (0.2, 1e-3), "contact_force_N": (0.15, 1.0), "contact_force_z_N": (0.15, 1.0)}


@pytest.mark.slow
def test_getup_evaluation_rollout_matches_mjx_on_the_first_tick():
    from sim_hil.launch import ROOT
    from training.evaluation.artifact_policy import ArtifactPolicy
    from training.evaluation.batch import make_rollout
    from training.evaluation.cpu import cpu_rollout
    policy = ArtifactPolicy.load(ROOT / "tests" / "golden" / "random_policy.safetensors")  # any policy will do
    qpos, qvel = envs.fallen_states(3, 0)
    over = {"fallen.bank_starts": 2}
    on_cpu = cpu_rollout(envs.make("getup", config_overrides={**over, "backend": "cpu"}), policy,
                         np.asarray(qpos), np.asarray(qvel), 1)
    on_mjx = make_rollout(envs.make("getup", config_overrides=over), policy, 1)(policy.params, qpos, qvel)
    assert set(on_cpu) == set(on_mjx)
    for key, (rtol, atol) in EVAL_TOL.items():
        np.testing.assert_allclose(on_cpu[key], np.asarray(on_mjx[key]), rtol=rtol, atol=atol, err_msg=key)
    assert np.any(on_cpu["contact_force_N"] > 0.0), "no contact compared"
    # flat floor: every world contact's normal is world z, so the vertical force is the normal force
    np.testing.assert_allclose(on_cpu["contact_force_z_N"], on_cpu["contact_force_N"], rtol=1e-5)


def test_target_noise_moves_the_rollout_reproducibly_and_is_refused_on_mjx():
    from sim_hil.launch import ROOT
    from training.evaluation.artifact_policy import ArtifactPolicy
    from training.evaluation.batch import run_policy
    from training.evaluation.cpu import cpu_rollout
    policy = ArtifactPolicy.load(ROOT / "tests" / "golden" / "random_policy.safetensors")
    qpos, qvel = (np.asarray(a) for a in envs.fallen_states(2, 0))
    env = envs.make("getup", config_overrides={"fallen.bank_starts": 2, "backend": "cpu"})
    plain, still = cpu_rollout(env, policy, qpos, qvel, 5), cpu_rollout(env, policy, qpos, qvel, 5, noise_seed=9)
    noisy, again = (cpu_rollout(env, policy, qpos, qvel, 5, target_noise_rad=0.05, noise_seed=3) for _ in range(2))
    np.testing.assert_array_equal(plain["readings"], still["readings"])
    np.testing.assert_array_equal(noisy["readings"], again["readings"])        # seeded
    assert not np.allclose(noisy["readings"][:, 1:], plain["readings"][:, 1:])   # the targets moved the robot
    with pytest.raises(ValueError, match="CPU backend"):
        run_policy(envs.make("getup", config_overrides={"fallen.bank_starts": 2}), policy, qpos, qvel, 0.1,
                   target_noise_rad=0.05)
    with pytest.raises(ValueError, match=">= 0"):
        run_policy(env, policy, qpos, qvel, 0.1, target_noise_rad=-1.0)


def test_the_host_profile_counts_physics_and_copies():
    """make bench-train's profile: every host step adds its env steps, C physics and copy seconds."""
    from tests.bench import train_bench
    from training.envs import cpu_backend
    rate = train_bench.raw_physics_rate("joystick", num_envs=4)
    assert rate > 0 and cpu_backend.PROFILE.env_steps == 4 * train_bench.RAW_CONTROL_STEPS
    assert cpu_backend.PROFILE.physics_s > 0 and cpu_backend.PROFILE.copies_s > 0


def test_the_bench_profile_times_each_part_of_a_ppo_step():
    """make bench-train's env JAX, policy-pass and update rows, at the toy preset's sizes."""
    from tests.bench import train_profile
    parts = train_profile.profile("joystick", preset="toy")
    assert set(parts) == {"env JAX", "policy pass", "update"}
    assert all(0.0 < s < 1.0 for s in parts.values()), parts     # seconds per env step
