"""The deployed runtime's target rule R6 in training (training/envs/motor.py supervised_target for MJX, the
C control callback of the CPU backend): its constants are the contract's (messages/contract.json supervisor.r6,
which the runtime's SafetyConfig reads too), its semantics R6's, and the two backends compute the same target."""
from __future__ import annotations

import jax.numpy as jnp
import mujoco
import numpy as np

from messages import contract
from training import envs
from training.envs import base, motor


def test_training_models_the_contracts_rule():
    """Training's R6 is the contract's (the runtime's SafetyConfig reads the same): 0.05 rad per 2 ms tick, 95 %."""
    sup = base.base_config().supervisor
    assert (sup.max_target_speed_rps, sup.joint_range_fraction) == (contract.R6_MAX_TARGET_SPEED_RPS,
                                                                    contract.R6_JOINT_RANGE_FRACTION)
    assert np.isclose(sup.max_target_speed_rps * contract.LOOP_PERIOD_S, 0.05) and sup.joint_range_fraction == 0.95


def _r6(wanted, last, q=0.0, dq=0.0, kp=100.0, kd=2.0, tau=10.0, lo=-1.0, hi=1.0, step=0.05):
    f = lambda x: jnp.asarray(x, jnp.float32)   # noqa: E731
    return float(motor.supervised_target(*(f(v) for v in (wanted, last, q, dq, kp, kd, tau, lo, hi, step))))


def test_rule_r6_rate_then_torque_then_range():
    assert np.isclose(_r6(0.5, 0.0), 0.05)                      # rate: 0.05 per tick
    assert np.isclose(_r6(0.02, 0.0), 0.02)                     # inside every limit: unchanged
    assert np.isclose(_r6(1.0, 0.08), 0.10)                     # torque: kp·t = 10 N·m at t = 0.1
    assert np.isclose(_r6(1.0, 0.08, dq=1.0), 0.12)             # ... the damping term moves it: (kd·dq + τ)/kp
    assert np.isclose(_r6(1.0, 0.5), 0.45)                      # torque bound out of rate reach: rate wins
    assert np.isclose(_r6(2.0, 0.97, q=0.95, tau=100.0), 1.0)   # range end
    assert np.isclose(_r6(2.0, 1.2, q=1.15, tau=100.0), 1.15)   # range out of rate reach: toward it at the rate


def test_cpu_callback_and_jax_compute_the_same_target():
    cfg = envs.default_config("joystick")
    cfg.backend = "cpu"
    env = envs.make("joystick", config=cfg)
    mj = env.mj_model
    d = mujoco.MjData(mj)
    kp, kd = mj.actuator_biasprm[:, 0].copy(), mj.actuator_biasprm[:, 1].copy()
    lo, hi = np.asarray(env._range_lo), np.asarray(env._range_hi)
    rng = np.random.default_rng(5)
    for case in range(50):
        wanted, last = rng.uniform(lo - 0.5, hi + 0.5), rng.uniform(lo - 0.2, hi + 0.2)
        q, dq = last + rng.uniform(-0.3, 0.3, 23), rng.uniform(-5, 5, 23)
        d.qpos[7:], d.qvel[6:] = q, dq
        d.userdata[:23], d.userdata[23:46] = wanted, last
        d.userdata[46:48] = env._target_step, cfg.supervisor.joint_range_fraction
        d.userdata[48] = env._cpu._lib.t1_mjcb_marker()
        mujoco.mj_forward(mj, d)                               # runs the control callback once
        expect = motor.supervised_target(*(jnp.asarray(v, jnp.float32) for v in (
            wanted, last, q, dq, kp, kd, np.asarray(env._tau_limit), lo, hi, env._target_step)))
        np.testing.assert_allclose(d.userdata[23:46], np.asarray(expect), atol=1e-5, err_msg=f"case {case}")
        assert np.all(np.abs(d.userdata[23:46] - last) <= env._target_step + 1e-9)


def test_a_target_jump_reaches_the_motors_at_the_runtimes_rate():
    """A full-scale action from standing: after one 20 ms control step the supervisor's target has moved
    10 ticks × 0.05 rad at most, as the deployed runtime would have sent (on MJX the same: the parity test
    of tests/test_cpu_backend.py, which compiles MJX's step anyway)."""
    import jax
    cfg = envs.default_config("getup_stand")
    cfg.backend = "cpu"
    env = envs.make("getup_stand", config=cfg)
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    before = np.asarray(state.info["runtime_target"])
    after = np.asarray(jax.jit(env.step)(state, jnp.ones(23)).info["runtime_target"])
    moved = np.abs(after - before)
    assert moved.max() <= env.n_substeps * env._target_step + 1e-5
    assert moved.max() > 0.5 * env.n_substeps * env._target_step   # and it did move toward the jump
