/* Per-motor firmware: command latch with validation, PD + feed-forward, torque clamp, soft stops,
 * command watchdog and power-on damping (t1_motor_protocol.h §6–§7). No heap, no globals written. */
#include <math.h>
#include <string.h>

#include "t1_firmware.h"

static float clampf(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }

int t1_motor_init(t1_motor_t* m, unsigned motor_index) {
  if (m == NULL) return T1_ERR_NULL;
  if (motor_index >= T1_NUM_MOTORS) return T1_ERR_BAD_INDEX;
  memset(m, 0, sizeof(*m));
  m->motor_index = (uint8_t)motor_index;
  m->status = (uint8_t)(T1_STATUS_POWER_ON | T1_STATUS_DAMPING);
  return T1_OK;
}

static void reject_frame(t1_motor_t* m) {
  m->bad_frame_latch = 1u;
  m->status = (uint8_t)(m->status | T1_STATUS_BAD_FRAME);
}

int t1_motor_receive(t1_motor_t* m, uint32_t can_id, const uint8_t* data, uint8_t dlc, uint64_t now_us) {
  if (m == NULL) return T1_ERR_NULL;
  if (data == NULL) {
    reject_frame(m);
    return T1_ERR_NULL;
  }
  if (can_id != T1_CMD_CAN_ID(m->motor_index)) {
    reject_frame(m);
    return T1_ERR_BAD_ID;
  }
  t1_command_t cmd;
  const int rc = t1_unpack_command(m->motor_index, data, dlc, &cmd);
  if (rc != T1_OK) {
    reject_frame(m);
    return rc;
  }
  /* Fixed-point decoding cannot produce a non-finite value; checked anyway because this is the only
   * gate between the bus and the torque computation. */
  if (!isfinite(cmd.q_des_rad) || !isfinite(cmd.dq_des_rads) || !isfinite(cmd.kp_nm_per_rad) ||
      !isfinite(cmd.kd_nms_per_rad) || !isfinite(cmd.tau_ff_nm)) {
    reject_frame(m);
    return T1_ERR_NONFINITE;
  }
  m->command = cmd;
  m->has_command = 1u;
  m->last_command_us = now_us;
  m->bad_frame_latch = 0u;
  /* A valid command clears BAD_FRAME, POWER_ON, WATCHDOG and DAMPING at once (the next step would
   * recompute the mode anyway; clearing here makes the very next reply truthful). */
  m->status = (uint8_t)(m->status & (T1_STATUS_OVER_LIMIT | T1_STATUS_BAD_SENSOR));
  return T1_OK;
}

/* Restoring spring-damper beyond a joint-range end; 0 inside the range. *beyond set if outside. */
static float soft_stop_torque(const t1_motor_info_t* info, float q, float dq, int* beyond) {
  const float k_stop = info->torque_limit_nm / T1_SOFT_STOP_FULL_TORQUE_RAD; /* N·m/rad */
  if (q < info->q_min_rad) {
    *beyond = 1;
    const float dq_out = dq < 0.0f ? dq : 0.0f; /* only the velocity that goes further out */
    return k_stop * (info->q_min_rad - q) - info->d_safe_nms * dq_out;
  }
  if (q > info->q_max_rad) {
    *beyond = 1;
    const float dq_out = dq > 0.0f ? dq : 0.0f;
    return k_stop * (info->q_max_rad - q) - info->d_safe_nms * dq_out;
  }
  *beyond = 0;
  return 0.0f;
}

float t1_motor_step(t1_motor_t* m, float q_rad, float dq_rads, uint64_t now_us) {
  if (m == NULL || m->motor_index >= T1_NUM_MOTORS) return 0.0f;
  const t1_motor_info_t* info = &T1_MOTORS[m->motor_index];
  uint8_t status = m->bad_frame_latch ? (uint8_t)T1_STATUS_BAD_FRAME : 0u;

  /* Mode. A clock that went backwards gives a huge unsigned age: that counts as a timeout (fail safe;
   * the simulator re-initialises motors on reset). */
  int damping = 0;
  if (!m->has_command) {
    damping = 1;
    status |= T1_STATUS_POWER_ON;
  } else if (now_us - m->last_command_us > (uint64_t)T1_WATCHDOG_US) {
    damping = 1;
    status |= T1_STATUS_WATCHDOG;
  }
  if (damping) status |= T1_STATUS_DAMPING;

  if (!isfinite(q_rad) || !isfinite(dq_rads)) {
    m->status = (uint8_t)(status | T1_STATUS_BAD_SENSOR);
    m->last_tau_nm = 0.0f;
    return 0.0f;
  }

  float tau;
  if (damping) {
    tau = -info->d_safe_nms * dq_rads;
  } else {
    const t1_command_t* c = &m->command;
    tau = c->kp_nm_per_rad * (c->q_des_rad - q_rad) + c->kd_nms_per_rad * (c->dq_des_rads - dq_rads) + c->tau_ff_nm;
  }
  int beyond = 0;
  tau += soft_stop_torque(info, q_rad, dq_rads, &beyond);

  const float limit = info->torque_limit_nm;
  /* q and dq are finite but can be huge: tau may overflow to ±inf, which the clamp still handles. */
  if (beyond || !(fabsf(tau) <= limit)) status |= T1_STATUS_OVER_LIMIT;
  tau = isnan(tau) ? 0.0f : clampf(tau, -limit, limit);

  m->status = status;
  m->last_tau_nm = tau;
  return tau;
}

int t1_motor_reply(const t1_motor_t* m, float q_rad, float dq_rads, float tau_nm, uint8_t out[T1_FRAME_SLOT_BYTES]) {
  if (m == NULL || out == NULL) return T1_ERR_NULL;
  const int rc = t1_pack_reply(m->motor_index, q_rad, dq_rads, tau_nm, m->status, out);
  if (rc != T1_OK) return rc;
  out[T1_FRAME_SLOT_BYTES - 1] = 0u; /* slot padding beyond the 7-byte reply */
  return T1_REPLY_DLC;
}
