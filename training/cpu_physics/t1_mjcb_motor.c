/*
 * t1_mjcb_motor.c — the firmware motor law as MuJoCo's control callback (mjcb_control), for the CPU
 * training backend (training/backends.py).
 *
 * MuJoCo calls mjcb_control inside every mj_step, i.e. at every physics substep, on whichever thread
 * steps that simulation (mujoco.batch runs simulations on a thread pool and the callback must be C).
 * Here each of the 23 motors runs firmware_like's own t1_motor_step — the code the simulated robot's
 * motors run — in normal mode with a fresh command every substep:
 *     command = { q_des from d->userdata[i], dq_des 0, kp / kd from the (possibly randomised) model's
 *                 actuator_biasprm[i][0 / 1], tau_ff 0 }       (what the runtime sends)
 *     d->ctrl[i] = t1_motor_step(...)  = clip(kp·(q_des − q) − kd·dq + soft stop, ±τ_limit)  [N·m]
 * The actuators are plain motors (τ = ctrl), so ctrl is the joint torque. The command is not packed
 * into a CAN frame: the MJX backend (training/envs/motor.py) does not quantise either, and the
 * quantisation is the bus emulation's business (sim_hil).
 *
 * mjcb_control is process-global: the callback acts only on models built for this backend, recognised
 * by nuserdata == T1_MJCB_NUSERDATA (23 targets + a marker), and leaves every other model alone.
 */
#include <mujoco/mujoco.h>

#include "t1_firmware.h"

#define T1_MJCB_NUSERDATA (T1_NUM_MOTORS + 1)
#define T1_MJCB_MARKER 1230.0 /* userdata[23]: a model built by training/backends.py */

int t1_mjcb_nuserdata(void);
double t1_mjcb_marker(void);
void t1_mjcb_motor(const mjModel* m, mjData* d);

int t1_mjcb_nuserdata(void) { return T1_MJCB_NUSERDATA; }
double t1_mjcb_marker(void) { return T1_MJCB_MARKER; }

void t1_mjcb_motor(const mjModel* m, mjData* d) {
  if (m->nuserdata != T1_MJCB_NUSERDATA || m->nu != T1_NUM_MOTORS ||
      d->userdata[T1_NUM_MOTORS] != T1_MJCB_MARKER) {
    return;
  }
  for (int i = 0; i < T1_NUM_MOTORS; ++i) {
    const int joint = m->actuator_trnid[2 * i];
    t1_motor_t motor;
    t1_motor_init(&motor, (unsigned)i);
    motor.has_command = 1; /* commanded this very substep: no watchdog, no power-on damping */
    motor.last_command_us = 0;
    motor.command.q_des_rad = (float)d->userdata[i];
    motor.command.dq_des_rads = 0.0f;
    motor.command.kp_nm_per_rad = (float)m->actuator_biasprm[i * mjNBIAS + 0];
    motor.command.kd_nms_per_rad = (float)m->actuator_biasprm[i * mjNBIAS + 1];
    motor.command.tau_ff_nm = 0.0f;
    d->ctrl[i] = (mjtNum)t1_motor_step(&motor, (float)d->qpos[m->jnt_qposadr[joint]],
                                       (float)d->qvel[m->jnt_dofadr[joint]], 0);
  }
}
