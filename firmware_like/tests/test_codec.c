/* Codec tests: round trip within one quantisation step over every field's whole range for every motor
 * class, saturation at the range edges, non-finite input refused, exact bit layout, reply frames. */
#include <math.h>
#include <string.h>

#include "t1_firmware.h"
#include "t1_test.h"

#define SWEEP_POINTS 2001

static double step_of(float lo, float hi, unsigned bits) { return ((double)hi - lo) / (double)((1u << bits) - 1u); }

/* One representative motor per class (first motor of that class in joint order). */
static unsigned motor_of_class(t1_motor_class_t c) {
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i)
    if (T1_MOTORS[i].motor_class == c) return i;
  return 0;
}

static void test_round_trip_every_class(void) {
  for (int c = T1_CLASS_HEAD; c <= T1_CLASS_ANKLE; ++c) {
    const unsigned m = motor_of_class((t1_motor_class_t)c);
    const float v = t1_motor_v_max_rads(m), t = t1_motor_t_max_nm(m);
    const double q_step = step_of(-T1_Q_MAX_RAD, T1_Q_MAX_RAD, T1_Q_BITS);
    const double v_step = step_of(-v, v, T1_DQ_BITS), t_step = step_of(-t, t, T1_TAU_BITS);
    const double kp_step = step_of(0.0f, T1_KP_MAX, T1_KP_BITS), kd_step = step_of(0.0f, T1_KD_MAX, T1_KD_BITS);
    for (int k = 0; k < SWEEP_POINTS; ++k) {
      const float u = (float)k / (float)(SWEEP_POINTS - 1); /* 0..1 */
      const t1_command_t in = {-T1_Q_MAX_RAD + 2.0f * T1_Q_MAX_RAD * u, -v + 2.0f * v * u, T1_KP_MAX * u,
                               T1_KD_MAX * (1.0f - u), t - 2.0f * t * u};
      uint8_t frame[8];
      t1_command_t out;
      CHECK(t1_pack_command(m, &in, frame) == T1_OK);
      CHECK(t1_unpack_command(m, frame, T1_CMD_DLC, &out) == T1_OK);
      CHECK_NEAR(out.q_des_rad, in.q_des_rad, q_step);
      CHECK_NEAR(out.dq_des_rads, in.dq_des_rads, v_step);
      CHECK_NEAR(out.kp_nm_per_rad, in.kp_nm_per_rad, kp_step);
      CHECK_NEAR(out.kd_nms_per_rad, in.kd_nms_per_rad, kd_step);
      CHECK_NEAR(out.tau_ff_nm, in.tau_ff_nm, t_step);

      uint8_t reply[8];
      t1_reply_t r;
      CHECK(t1_pack_reply(m, in.q_des_rad, in.dq_des_rads, in.tau_ff_nm, 0x00u, reply) == T1_OK);
      CHECK(t1_unpack_reply(reply, T1_REPLY_DLC, &r) == T1_OK);
      CHECK(r.motor_id == m + 1u);
      CHECK_NEAR(r.q_rad, in.q_des_rad, q_step);
      CHECK_NEAR(r.dq_rads, in.dq_des_rads, v_step);
      CHECK_NEAR(r.tau_nm, in.tau_ff_nm, t_step);
    }
  }
}

static void test_saturation_at_edges(void) {
  const unsigned knee = 14;
  const t1_command_t beyond = {100.0f, 1e6f, 1e4f, 1e3f, -1e9f};
  const t1_command_t edge = {T1_Q_MAX_RAD, T1_KNEE_V_MAX_RADS, T1_KP_MAX, T1_KD_MAX, -T1_KNEE_T_MAX_NM};
  uint8_t a[8], b[8];
  CHECK(t1_pack_command(knee, &beyond, a) == T1_OK);
  CHECK(t1_pack_command(knee, &edge, b) == T1_OK);
  CHECK(memcmp(a, b, 8) == 0); /* beyond the range encodes exactly as the edge */
  t1_command_t out;
  CHECK(t1_unpack_command(knee, a, T1_CMD_DLC, &out) == T1_OK);
  CHECK(out.q_des_rad == T1_Q_MAX_RAD);
  CHECK(out.kp_nm_per_rad == T1_KP_MAX);
  CHECK(out.tau_ff_nm == -T1_KNEE_T_MAX_NM);
  CHECK(t1_float_to_code(-5.0f, -4.0f, 4.0f, 16) == 0u);
  CHECK(t1_float_to_code(5.0f, -4.0f, 4.0f, 16) == 0xFFFFu);
  CHECK(t1_float_to_code(-INFINITY, -4.0f, 4.0f, 16) == 0u);
  CHECK(t1_float_to_code(INFINITY, -4.0f, 4.0f, 16) == 0xFFFFu);
  /* Negative gains are below the range: they encode as 0 (a motor can never get negative stiffness). */
  const t1_command_t neg = {0.0f, 0.0f, -50.0f, -1.0f, 0.0f};
  CHECK(t1_pack_command(knee, &neg, a) == T1_OK);
  CHECK(t1_unpack_command(knee, a, T1_CMD_DLC, &out) == T1_OK);
  CHECK(out.kp_nm_per_rad == 0.0f && out.kd_nms_per_rad == 0.0f);
}

static void test_nonfinite_refused(void) {
  const float bad[3] = {NAN, INFINITY, -INFINITY};
  for (int f = 0; f < 5; ++f) {
    for (int k = 0; k < 3; ++k) {
      t1_command_t c = {0.1f, 0.2f, 30.0f, 2.0f, 1.0f};
      float* field = f == 0   ? &c.q_des_rad
                     : f == 1 ? &c.dq_des_rads
                     : f == 2 ? &c.kp_nm_per_rad
                     : f == 3 ? &c.kd_nms_per_rad
                              : &c.tau_ff_nm;
      *field = bad[k];
      uint8_t frame[8] = {0xA5, 0xA5, 0xA5, 0xA5, 0xA5, 0xA5, 0xA5, 0xA5};
      CHECK(t1_pack_command(3, &c, frame) == T1_ERR_NONFINITE);
      CHECK(frame[0] == 0xA5 && frame[7] == 0xA5); /* untouched: nothing to send */
    }
  }
  /* A non-finite measurement in a reply becomes 0 + BAD_SENSOR, never a number. */
  uint8_t reply[8];
  t1_reply_t r;
  CHECK(t1_pack_reply(0, NAN, 1.0f, 0.5f, 0x00u, reply) == T1_OK);
  CHECK(t1_unpack_reply(reply, T1_REPLY_DLC, &r) == T1_OK);
  CHECK(r.status & T1_STATUS_BAD_SENSOR);
  CHECK(fabsf(r.q_rad) < 1e-3f);
}

/* Exact bit layout: codes written by hand, checked against the documented byte formulas. */
static void test_bit_layout(void) {
  /* q = 0x1234, dq = 0xABC, kp = 0xDEF, kd = 0x135, tau = 0x79B */
  const uint8_t frame[8] = {0x12, 0x34, 0xAB, 0xCD, 0xEF, 0x13, 0x57, 0x9B};
  t1_command_t c;
  const unsigned hip = 11;
  CHECK(t1_unpack_command(hip, frame, 8, &c) == T1_OK);
  CHECK_NEAR(c.q_des_rad, t1_code_to_float(0x1234u, -4.0f, 4.0f, 16), 0.0);
  CHECK_NEAR(c.dq_des_rads, t1_code_to_float(0xABCu, -T1_HIP_V_MAX_RADS, T1_HIP_V_MAX_RADS, 12), 0.0);
  CHECK_NEAR(c.kp_nm_per_rad, t1_code_to_float(0xDEFu, 0.0f, T1_KP_MAX, 12), 0.0);
  CHECK_NEAR(c.kd_nms_per_rad, t1_code_to_float(0x135u, 0.0f, T1_KD_MAX, 12), 0.0);
  CHECK_NEAR(c.tau_ff_nm, t1_code_to_float(0x79Bu, -T1_HIP_T_MAX_NM, T1_HIP_T_MAX_NM, 12), 0.0);
  uint8_t again[8];
  CHECK(t1_pack_command(hip, &c, again) == T1_OK);
  CHECK(memcmp(again, frame, 8) == 0);
  /* Reply: id 12, q 0x8000, dq 0x800, tau 0x7FF, status 0x03 */
  const uint8_t reply[7] = {12, 0x80, 0x00, 0x80, 0x07, 0xFF, 0x03};
  t1_reply_t r;
  CHECK(t1_unpack_reply(reply, 7, &r) == T1_OK);
  CHECK(r.motor_id == 12 && r.status == 0x03);
  CHECK_NEAR(r.q_rad, t1_code_to_float(0x8000u, -4.0f, 4.0f, 16), 0.0);
  CHECK_NEAR(r.tau_nm, t1_code_to_float(0x7FFu, -T1_HIP_T_MAX_NM, T1_HIP_T_MAX_NM, 12), 0.0);
}

static void test_malformed(void) {
  uint8_t frame[8] = {0};
  t1_command_t c;
  t1_reply_t r;
  CHECK(t1_unpack_command(0, frame, 7, &c) == T1_ERR_BAD_DLC);
  CHECK(t1_unpack_command(23, frame, 8, &c) == T1_ERR_BAD_INDEX);
  CHECK(t1_unpack_reply(frame, 7, &r) == T1_ERR_BAD_ID); /* motor id 0 never exists */
  frame[0] = 24;
  CHECK(t1_unpack_reply(frame, 7, &r) == T1_ERR_BAD_ID);
  frame[0] = 1;
  CHECK(t1_unpack_reply(frame, 8, &r) == T1_ERR_BAD_DLC);
  CHECK(t1_pack_command(0, NULL, frame) == T1_ERR_NULL);
}

static void test_table(void) {
  CHECK(strcmp(T1_MOTORS[0].name, "AAHead_yaw") == 0);
  CHECK(strcmp(T1_MOTORS[22].name, "Right_Ankle_Roll") == 0);
  int per_bus[T1_NUM_BUSES] = {0};
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    const t1_motor_info_t* m = &T1_MOTORS[i];
    per_bus[m->bus]++;
    CHECK(m->torque_limit_nm <= T1_CLASS_RANGES[m->motor_class].t_max_nm);
    CHECK(m->q_min_rad >= -T1_Q_MAX_RAD && m->q_max_rad <= T1_Q_MAX_RAD && m->q_min_rad < m->q_max_rad);
    CHECK(m->d_safe_nms > 0.0f && m->d_safe_nms <= T1_KD_MAX);
  }
  CHECK(per_bus[0] == 6 && per_bus[1] == 6 && per_bus[2] == 8 && per_bus[3] == 3);
  CHECK(T1_CMD_CAN_ID(0) == 0x101u && T1_REPLY_CAN_ID(22) == 0x217u);
}

int main(void) {
  test_round_trip_every_class();
  test_saturation_at_edges();
  test_nonfinite_refused();
  test_bit_layout();
  test_malformed();
  test_table();
  return t1_test_report("test_codec");
}
