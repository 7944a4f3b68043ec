/*
 * t1_mjcb_motor.c — the firmware motor law as MuJoCo's control callback (mjcb_control), for the CPU
 * training backend (training/backends.py).
 *
 * MuJoCo calls mjcb_control inside every mj_step, i.e. at every physics substep, on whichever thread
 * steps that simulation (mujoco.batch runs simulations on a thread pool and the callback must be C).
 * One substep is one 2 ms tick of the deployed runtime: first its supervisor's target rule R6
 * (runtime/src/safety_supervisor.cpp clamp_targets; training/envs/motor.py supervised_target restates it
 * for MJX): from the policy's wanted target, the point nearest to it that is
 *     1. within ±max_step of the last target, 2. within reach of the torque limit from q, dq,
 *     3. within the centred range fraction of the joint range (each as far as the ones before allow);
 * then each of the 23 motors runs firmware_like's own t1_motor_step — the code the simulated robot's
 * motors run — in normal mode with a fresh command every substep:
 *     command = { q_des = that target, dq_des 0, kp / kd from the (possibly randomised) model's
 *                 actuator_biasprm[i][0 / 1], tau_ff 0 }       (what the runtime sends)
 *     d->ctrl[i] = t1_motor_step(...)  = clip(kp·(q_des − q) − kd·dq + soft stop, ±τ_limit)  [N·m]
 * d->userdata: [0, 23) the wanted targets [rad], [23, 46) the last targets (read and written here),
 * [46] max_step [rad per substep], [47] range fraction, [48] the marker.
 * The actuators are plain motors (τ = ctrl), so ctrl is the joint torque. The command is not packed
 * into a CAN frame: the MJX backend (training/envs/motor.py) does not quantise either, and the
 * quantisation is the bus emulation's business (sim_hil).
 *
 * mjcb_control is process-global: the callback acts only on models built for this backend, recognised
 * by nuserdata == T1_MJCB_NUSERDATA (23 targets + a marker), and leaves every other model alone.
 */
#include <mujoco/mujoco.h>

#include "t1_firmware.h"

#define T1_MJCB_LAST (T1_NUM_MOTORS)           /* userdata offset of the last targets */
#define T1_MJCB_MAX_STEP (2 * T1_NUM_MOTORS)   /* rad per substep */
#define T1_MJCB_RANGE_FRACTION (2 * T1_NUM_MOTORS + 1)
#define T1_MJCB_MARKER_AT (2 * T1_NUM_MOTORS + 2)
#define T1_MJCB_NUSERDATA (2 * T1_NUM_MOTORS + 3)
#define T1_MJCB_MARKER 1230.0 /* userdata[T1_MJCB_MARKER_AT]: a model built by training/backends.py */

int t1_mjcb_nuserdata(void);
double t1_mjcb_marker(void);
void t1_mjcb_motor(const mjModel* m, mjData* d);

int t1_mjcb_nuserdata(void) { return T1_MJCB_NUSERDATA; }
double t1_mjcb_marker(void) { return T1_MJCB_MARKER; }

/* [lo, hi] narrowed to [lim_lo, lim_hi], or to the end of [lo, hi] nearest to it when they do not meet */
static void narrow(double* lo, double* hi, double lim_lo, double lim_hi) {
  if (lim_hi < *lo) {
    *hi = *lo;
  } else if (lim_lo > *hi) {
    *lo = *hi;
  } else {
    if (lim_lo > *lo) *lo = lim_lo;
    if (lim_hi < *hi) *hi = lim_hi;
  }
}

void t1_mjcb_motor(const mjModel* m, mjData* d) {
  if (m->nuserdata != T1_MJCB_NUSERDATA || m->nu != T1_NUM_MOTORS ||
      d->userdata[T1_MJCB_MARKER_AT] != T1_MJCB_MARKER) {
    return;
  }
  const double max_step = d->userdata[T1_MJCB_MAX_STEP];
  const double fraction = d->userdata[T1_MJCB_RANGE_FRACTION];
  for (int i = 0; i < T1_NUM_MOTORS; ++i) {
    const int joint = m->actuator_trnid[2 * i];
    const double q = d->qpos[m->jnt_qposadr[joint]], dq = d->qvel[m->jnt_dofadr[joint]];
    const double kp = m->actuator_biasprm[i * mjNBIAS + 0], kd = m->actuator_biasprm[i * mjNBIAS + 1];
    const t1_motor_info_t* info = &T1_MOTORS[i];
    /* the runtime's R6: rate, torque, range; then the nearest point to the wanted target */
    double lo = d->userdata[T1_MJCB_LAST + i] - max_step, hi = d->userdata[T1_MJCB_LAST + i] + max_step;
    narrow(&lo, &hi, q + (kd * dq - info->torque_limit_nm) / kp, q + (kd * dq + info->torque_limit_nm) / kp);
    const double mid = 0.5 * (info->q_min_rad + info->q_max_rad);
    const double half = 0.5 * (info->q_max_rad - info->q_min_rad) * fraction;
    narrow(&lo, &hi, mid - half, mid + half);
    const double wanted = d->userdata[i];
    const double target = wanted < lo ? lo : (wanted > hi ? hi : wanted);
    d->userdata[T1_MJCB_LAST + i] = target;

    t1_motor_t motor;
    t1_motor_init(&motor, (unsigned)i);
    motor.has_command = 1; /* commanded this very substep: no watchdog, no power-on damping */
    motor.last_command_us = 0;
    motor.command.q_des_rad = (float)target;
    motor.command.dq_des_rads = 0.0f;
    motor.command.kp_nm_per_rad = (float)kp;
    motor.command.kd_nms_per_rad = (float)kd;
    motor.command.tau_ff_nm = 0.0f;
    d->ctrl[i] = (mjtNum)t1_motor_step(&motor, (float)q, (float)dq, 0);
  }
}
