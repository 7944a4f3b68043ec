/* Frame codec: MIT mini-cheetah style fixed-point packing (t1_motor_protocol.h §3–§5). */
#include <math.h>

#include "t1_firmware.h"

static int all_finite5(const t1_command_t* c) {
  return isfinite(c->q_des_rad) && isfinite(c->dq_des_rads) && isfinite(c->kp_nm_per_rad) &&
         isfinite(c->kd_nms_per_rad) && isfinite(c->tau_ff_nm);
}

static uint32_t max_code(unsigned bits) { return (1u << bits) - 1u; }

uint32_t t1_float_to_code(float x, float lo, float hi, unsigned bits) {
  const uint32_t top = max_code(bits);
  /* !(x > lo) also catches NaN: a NaN that slipped through encodes as the low edge, never as garbage. */
  if (!(x > lo)) return 0u;
  if (x >= hi) return top;
  /* Round to nearest so the round-trip error is at most half a step (mini-cheetah truncates). */
  const float scaled = (x - lo) * ((float)top / (hi - lo)) + 0.5f;
  const uint32_t code = (uint32_t)scaled;
  return code > top ? top : code;
}

float t1_code_to_float(uint32_t code, float lo, float hi, unsigned bits) {
  const uint32_t top = max_code(bits);
  if (code > top) code = top;
  return lo + (float)code * ((hi - lo) / (float)top);
}

float t1_motor_v_max_rads(unsigned motor_index) {
  if (motor_index >= T1_NUM_MOTORS) return 0.0f;
  return T1_CLASS_RANGES[T1_MOTORS[motor_index].motor_class].v_max_rads;
}

float t1_motor_t_max_nm(unsigned motor_index) {
  if (motor_index >= T1_NUM_MOTORS) return 0.0f;
  return T1_CLASS_RANGES[T1_MOTORS[motor_index].motor_class].t_max_nm;
}

int t1_pack_command(unsigned motor_index, const t1_command_t* cmd, uint8_t out[T1_CMD_DLC]) {
  if (cmd == NULL || out == NULL) return T1_ERR_NULL;
  if (motor_index >= T1_NUM_MOTORS) return T1_ERR_BAD_INDEX;
  if (!all_finite5(cmd)) return T1_ERR_NONFINITE;
  const float v = t1_motor_v_max_rads(motor_index);
  const float t = t1_motor_t_max_nm(motor_index);
  const uint32_t q = t1_float_to_code(cmd->q_des_rad, -T1_Q_MAX_RAD, T1_Q_MAX_RAD, T1_Q_BITS);
  const uint32_t dq = t1_float_to_code(cmd->dq_des_rads, -v, v, T1_DQ_BITS);
  const uint32_t kp = t1_float_to_code(cmd->kp_nm_per_rad, 0.0f, T1_KP_MAX, T1_KP_BITS);
  const uint32_t kd = t1_float_to_code(cmd->kd_nms_per_rad, 0.0f, T1_KD_MAX, T1_KD_BITS);
  const uint32_t tau = t1_float_to_code(cmd->tau_ff_nm, -t, t, T1_TAU_BITS);
  out[0] = (uint8_t)(q >> 8);
  out[1] = (uint8_t)(q & 0xFFu);
  out[2] = (uint8_t)(dq >> 4);
  out[3] = (uint8_t)(((dq & 0xFu) << 4) | (kp >> 8));
  out[4] = (uint8_t)(kp & 0xFFu);
  out[5] = (uint8_t)(kd >> 4);
  out[6] = (uint8_t)(((kd & 0xFu) << 4) | (tau >> 8));
  out[7] = (uint8_t)(tau & 0xFFu);
  return T1_OK;
}

int t1_unpack_command(unsigned motor_index, const uint8_t* data, uint8_t dlc, t1_command_t* out) {
  if (data == NULL || out == NULL) return T1_ERR_NULL;
  if (motor_index >= T1_NUM_MOTORS) return T1_ERR_BAD_INDEX;
  if (dlc != T1_CMD_DLC) return T1_ERR_BAD_DLC;
  const float v = t1_motor_v_max_rads(motor_index);
  const float t = t1_motor_t_max_nm(motor_index);
  const uint32_t q = ((uint32_t)data[0] << 8) | data[1];
  const uint32_t dq = ((uint32_t)data[2] << 4) | ((uint32_t)data[3] >> 4);
  const uint32_t kp = (((uint32_t)data[3] & 0xFu) << 8) | data[4];
  const uint32_t kd = ((uint32_t)data[5] << 4) | ((uint32_t)data[6] >> 4);
  const uint32_t tau = (((uint32_t)data[6] & 0xFu) << 8) | data[7];
  out->q_des_rad = t1_code_to_float(q, -T1_Q_MAX_RAD, T1_Q_MAX_RAD, T1_Q_BITS);
  out->dq_des_rads = t1_code_to_float(dq, -v, v, T1_DQ_BITS);
  out->kp_nm_per_rad = t1_code_to_float(kp, 0.0f, T1_KP_MAX, T1_KP_BITS);
  out->kd_nms_per_rad = t1_code_to_float(kd, 0.0f, T1_KD_MAX, T1_KD_BITS);
  out->tau_ff_nm = t1_code_to_float(tau, -t, t, T1_TAU_BITS);
  return T1_OK;
}

int t1_pack_reply(unsigned motor_index, float q_rad, float dq_rads, float tau_nm, uint8_t status,
                  uint8_t out[T1_REPLY_DLC]) {
  if (out == NULL) return T1_ERR_NULL;
  if (motor_index >= T1_NUM_MOTORS) return T1_ERR_BAD_INDEX;
  /* A non-finite measurement is reported through the status byte, never as a number. */
  if (!isfinite(q_rad) || !isfinite(dq_rads) || !isfinite(tau_nm)) {
    status = (uint8_t)(status | T1_STATUS_BAD_SENSOR);
    if (!isfinite(q_rad)) q_rad = 0.0f;
    if (!isfinite(dq_rads)) dq_rads = 0.0f;
    if (!isfinite(tau_nm)) tau_nm = 0.0f;
  }
  const float v = t1_motor_v_max_rads(motor_index);
  const float t = t1_motor_t_max_nm(motor_index);
  const uint32_t q = t1_float_to_code(q_rad, -T1_Q_MAX_RAD, T1_Q_MAX_RAD, T1_Q_BITS);
  const uint32_t dq = t1_float_to_code(dq_rads, -v, v, T1_DQ_BITS);
  const uint32_t tau = t1_float_to_code(tau_nm, -t, t, T1_TAU_BITS);
  out[0] = T1_MOTOR_ID_OF_INDEX(motor_index);
  out[1] = (uint8_t)(q >> 8);
  out[2] = (uint8_t)(q & 0xFFu);
  out[3] = (uint8_t)(dq >> 4);
  out[4] = (uint8_t)(((dq & 0xFu) << 4) | (tau >> 8));
  out[5] = (uint8_t)(tau & 0xFFu);
  out[6] = status;
  return T1_OK;
}

int t1_unpack_reply(const uint8_t* data, uint8_t dlc, t1_reply_t* out) {
  if (data == NULL || out == NULL) return T1_ERR_NULL;
  if (dlc != T1_REPLY_DLC) return T1_ERR_BAD_DLC;
  const uint8_t motor_id = data[0];
  if (motor_id < 1u || motor_id > T1_NUM_MOTORS) return T1_ERR_BAD_ID;
  const unsigned index = (unsigned)motor_id - 1u;
  const float v = t1_motor_v_max_rads(index);
  const float t = t1_motor_t_max_nm(index);
  const uint32_t q = ((uint32_t)data[1] << 8) | data[2];
  const uint32_t dq = ((uint32_t)data[3] << 4) | ((uint32_t)data[4] >> 4);
  const uint32_t tau = (((uint32_t)data[4] & 0xFu) << 8) | data[5];
  out->motor_id = motor_id;
  out->q_rad = t1_code_to_float(q, -T1_Q_MAX_RAD, T1_Q_MAX_RAD, T1_Q_BITS);
  out->dq_rads = t1_code_to_float(dq, -v, v, T1_DQ_BITS);
  out->tau_nm = t1_code_to_float(tau, -t, t, T1_TAU_BITS);
  out->status = data[6];
  return T1_OK;
}
