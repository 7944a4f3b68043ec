"""The motor law of firmware_like (t1_motor.c, t1_motor_protocol.h §6), in JAX, for the MJX envs.

Normal mode only (a training env always sends a fresh command, so watchdog / power-on damping never
triggers):  τ = kp·(q_des − q) + kd·(0 − dq)  [dq_des = 0, τ_ff = 0, as the runtime sends]
            + soft stop beyond a joint-range end: k_stop·(q_stop − q) − d_safe·dq_outward,
              k_stop = τ_limit / SOFT_STOP_FULL_TORQUE_RAD, the damper only on the outward velocity
            clamped to ±τ_limit (per joint).
The soft stop costs two `where`s per joint and is included so a policy never learns to lean on a stop
that the firmware would push back from. Joint limits are also MuJoCo constraints in the model, so the
soft stop rarely acts (only on penetration of the limit).

The per-motor constants restate the firmware table (T1_MOTOR_TABLE); tests/test_training_envs.py checks
them against sim_hil.firmware (which reads them from the compiled firmware library) and checks the
torques against MotorArray.step on the same inputs.
"""
from __future__ import annotations

import jax.numpy as jnp
import numpy as np

# t1_motor_protocol.h: T1_SOFT_STOP_FULL_TORQUE_RAD — the stop spring reaches the limit 0.1 rad past a stop.
SOFT_STOP_FULL_TORQUE_RAD = 0.1
# t1_motor_protocol.h T1_MOTOR_TABLE d_safe [N·m·s/rad] = torque limit / URDF velocity limit, joint order.
D_SAFE_NMS = np.array([0.56, 0.56, 0.96, 0.96, 0.96, 0.96, 0.96, 0.96, 0.96, 0.96, 2.76,
                       3.60, 2.75, 2.75, 5.13, 1.06, 1.21, 3.60, 2.75, 2.75, 5.13, 1.06, 1.21])


def soft_stop_torque(q, dq, q_min, q_max, tau_limit, d_safe):
    """Restoring spring-damper beyond a joint-range end [N·m]; 0 inside the range."""
    k_stop = tau_limit / SOFT_STOP_FULL_TORQUE_RAD
    below = k_stop * (q_min - q) - d_safe * jnp.minimum(dq, 0.0)
    above = k_stop * (q_max - q) - d_safe * jnp.maximum(dq, 0.0)
    return jnp.where(q < q_min, below, jnp.where(q > q_max, above, 0.0))


def motor_torque(q_des, q, dq, kp, kd, tau_limit, q_min, q_max, d_safe):
    """Firmware motor step, normal mode: clip(kp·(q_des − q) − kd·dq + soft stop, ±τ_limit) [N·m]."""
    tau = kp * (q_des - q) - kd * dq + soft_stop_torque(q, dq, q_min, q_max, tau_limit, d_safe)
    return jnp.clip(tau, -tau_limit, tau_limit)


def supervised_target(wanted, last, q, dq, kp, kd, tau_limit, range_lo, range_hi, max_step):
    """The runtime supervisor's target rule R6 (runtime/src/safety_supervisor.cpp, clamp_targets), which
    shapes every command the robot's motors get, once per 2 ms runtime tick [rad]:
      1. rate: within ±max_step of the last commanded target;
      2. torque: kp·(t − q) − kd·dq within ±τ_limit, as far as reachable under 1;
      3. range: within [range_lo, range_hi] (the centred joint_range_fraction), as far as reachable under 1, 2;
    the point of what is left nearest to the wanted target. Why it is modelled in training: without it a
    policy learns target jumps the deployed runtime never sends (a kneel-to-stand lunge that stood in
    training fell at once in the loop)."""
    lo, hi = last - max_step, last + max_step
    t_lo, t_hi = q + (kd * dq - tau_limit) / kp, q + (kd * dq + tau_limit) / kp
    lo, hi = _narrow(lo, hi, t_lo, t_hi)
    lo, hi = _narrow(lo, hi, range_lo, range_hi)
    return jnp.clip(wanted, lo, hi)


def _narrow(lo, hi, lim_lo, lim_hi):
    """[lo, hi] ∩ [lim_lo, lim_hi], or the end of [lo, hi] nearest to the limit when they do not meet."""
    new_lo = jnp.where(lim_hi < lo, lo, jnp.where(lim_lo > hi, hi, jnp.maximum(lo, lim_lo)))
    new_hi = jnp.where(lim_hi < lo, lo, jnp.where(lim_lo > hi, hi, jnp.minimum(hi, lim_hi)))
    return new_lo, new_hi
