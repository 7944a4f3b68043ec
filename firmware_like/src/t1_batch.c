/* Batch helpers: the simulator makes one call per tick for all 23 motors instead of 23 calls. */
#include <math.h>
#include <string.h>

#include "t1_firmware.h"

/* Finite doubles beyond this magnitude are clamped before the cast to float: converting a double
 * outside float's range is undefined behaviour in C, and every physical quantity here is far below. */
#define F64_TO_F32_LIMIT 1.0e30

static float to_f32(double x) {
  if (x > F64_TO_F32_LIMIT) return (float)F64_TO_F32_LIMIT;
  if (x < -F64_TO_F32_LIMIT) return (float)-F64_TO_F32_LIMIT;
  return (float)x; /* NaN stays NaN: the callee's isfinite check sees it */
}

size_t t1_motor_array_size(void) { return sizeof(t1_motor_array_t); }
size_t t1_bus_array_size(void) { return sizeof(t1_bus_array_t); }

void t1_motor_array_init(t1_motor_array_t* a) {
  if (a == NULL) return;
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) (void)t1_motor_init(&a->motors[i], i);
}

int t1_bus_array_init(t1_bus_array_t* b) {
  if (b == NULL) return T1_ERR_NULL;
  for (unsigned i = 0; i < T1_NUM_BUSES; ++i) {
    const int rc = t1_bus_init(&b->buses[i], i, T1_BUS_BITRATE_BPS, T1_BUS_CYCLE_US);
    if (rc != T1_OK) return rc;
  }
  return T1_OK;
}

uint32_t t1_batch_pack_commands(const double* q_des, const double* dq_des, const double* kp, const double* kd,
                                const double* tau_ff, uint8_t* out) {
  uint32_t bad = 0u;
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    uint8_t* slot = out + (size_t)i * T1_FRAME_SLOT_BYTES;
    const t1_command_t c = {to_f32(q_des[i]), to_f32(dq_des[i]), to_f32(kp[i]), to_f32(kd[i]), to_f32(tau_ff[i])};
    if (t1_pack_command(i, &c, slot) != T1_OK) {
      memset(slot, 0, T1_FRAME_SLOT_BYTES);
      bad |= 1u << i;
    }
  }
  return bad;
}

uint32_t t1_batch_receive(t1_motor_array_t* a, const uint8_t* frames, uint32_t deliver_mask, uint64_t now_us) {
  uint32_t rejected = 0u;
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    if (!(deliver_mask & (1u << i))) continue;
    const int rc =
        t1_motor_receive(&a->motors[i], T1_CMD_CAN_ID(i), frames + (size_t)i * T1_FRAME_SLOT_BYTES, T1_CMD_DLC, now_us);
    if (rc != T1_OK) rejected |= 1u << i;
  }
  return rejected;
}

void t1_batch_step(t1_motor_array_t* a, const double* q, const double* dq, uint64_t now_us, double* tau_out) {
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i)
    tau_out[i] = (double)t1_motor_step(&a->motors[i], to_f32(q[i]), to_f32(dq[i]), now_us);
}

void t1_batch_replies(const t1_motor_array_t* a, const double* q, const double* dq, const double* tau, uint8_t* out) {
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i)
    (void)t1_motor_reply(&a->motors[i], to_f32(q[i]), to_f32(dq[i]), to_f32(tau[i]),
                         out + (size_t)i * T1_FRAME_SLOT_BYTES);
}

uint32_t t1_batch_unpack_replies(const uint8_t* frames, double* q, double* dq, double* tau, int32_t* status) {
  uint32_t bad = 0u;
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    t1_reply_t r;
    const int rc = t1_unpack_reply(frames + (size_t)i * T1_FRAME_SLOT_BYTES, T1_REPLY_DLC, &r);
    if (rc != T1_OK || r.motor_id != T1_MOTOR_ID_OF_INDEX(i)) {
      q[i] = dq[i] = tau[i] = (double)NAN;
      status[i] = T1_BATCH_NO_REPLY_STATUS;
      bad |= 1u << i;
      continue;
    }
    q[i] = (double)r.q_rad;
    dq[i] = (double)r.dq_rads;
    tau[i] = (double)r.tau_nm;
    status[i] = (int32_t)r.status;
  }
  return bad;
}

void t1_batch_unpack_commands(const uint8_t* frames, double* q_des, double* dq_des, double* kp, double* kd,
                              double* tau_ff) {
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    t1_command_t c;
    (void)t1_unpack_command(i, frames + (size_t)i * T1_FRAME_SLOT_BYTES, T1_CMD_DLC, &c);
    q_des[i] = (double)c.q_des_rad;
    dq_des[i] = (double)c.dq_des_rads;
    kp[i] = (double)c.kp_nm_per_rad;
    kd[i] = (double)c.kd_nms_per_rad;
    tau_ff[i] = (double)c.tau_ff_nm;
  }
}

void t1_batch_status(const t1_motor_array_t* a, int32_t* status) {
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) status[i] = (int32_t)a->motors[i].status;
}

void t1_batch_bus_cycle(t1_bus_array_t* b, uint64_t now_us, const uint8_t* commands, uint32_t cmd_mask,
                        const uint8_t* replies, uint8_t* cmd_on_time, uint8_t* reply_on_time) {
  for (unsigned k = 0; k < T1_NUM_BUSES; ++k) t1_bus_begin_cycle(&b->buses[k], now_us);
  /* Joint order is id order, and every command id is below every reply id: this is the order in which
   * arbitration would put the frames on each bus if they were all pending at the cycle start. */
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    if (!(cmd_mask & (1u << i))) {
      cmd_on_time[i] = 0u;
      continue;
    }
    const int rc = t1_bus_submit(&b->buses[T1_MOTORS[i].bus], T1_CMD_CAN_ID(i),
                                 commands + (size_t)i * T1_FRAME_SLOT_BYTES, T1_CMD_DLC);
    cmd_on_time[i] = (uint8_t)(rc == T1_BUS_ON_TIME);
  }
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    const int rc = t1_bus_submit(&b->buses[T1_MOTORS[i].bus], T1_REPLY_CAN_ID(i),
                                 replies + (size_t)i * T1_FRAME_SLOT_BYTES, T1_REPLY_DLC);
    reply_on_time[i] = (uint8_t)(rc == T1_BUS_ON_TIME);
  }
}
