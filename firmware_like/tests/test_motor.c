/* Motor step tests: power-on damping, PD formula, torque clamp, watchdog damping after 50 ms of silence
 * (and not before), soft stops, malformed frames → BAD_FRAME (latched until a valid command). */
#include <math.h>
#include <string.h>

#include "t1_firmware.h"
#include "t1_test.h"

enum { HIP = 11, KNEE = 14, ANKLE_ROLL = 16 };

static void send(t1_motor_t* m, unsigned i, t1_command_t c, uint64_t now_us) {
  uint8_t frame[8];
  CHECK(t1_pack_command(i, &c, frame) == T1_OK);
  CHECK(t1_motor_receive(m, T1_CMD_CAN_ID(i), frame, T1_CMD_DLC, now_us) == T1_OK);
}

/* The command as the motor sees it (after quantisation). */
static t1_command_t quantised(unsigned i, t1_command_t c) {
  uint8_t frame[8];
  t1_command_t q;
  (void)t1_pack_command(i, &c, frame);
  (void)t1_unpack_command(i, frame, T1_CMD_DLC, &q);
  return q;
}

static void test_power_on_damping(void) {
  t1_motor_t m;
  CHECK(t1_motor_init(&m, HIP) == T1_OK);
  const float tau = t1_motor_step(&m, 0.1f, 2.0f, 0);
  CHECK_NEAR(tau, -T1_MOTORS[HIP].d_safe_nms * 2.0f, 1e-5);
  CHECK(m.status & T1_STATUS_POWER_ON);
  CHECK(m.status & T1_STATUS_DAMPING);
  CHECK(!(m.status & T1_STATUS_WATCHDOG));
}

static void test_pd_formula_and_clamp(void) {
  t1_motor_t m;
  t1_motor_init(&m, KNEE);
  const t1_command_t c = {0.8f, 0.5f, 40.0f, 2.0f, 3.0f};
  send(&m, KNEE, c, 1000);
  CHECK(m.status == 0u);
  const t1_command_t qc = quantised(KNEE, c);
  const float q = 0.7f, dq = -0.3f;
  const float expect = qc.kp_nm_per_rad * (qc.q_des_rad - q) + qc.kd_nms_per_rad * (qc.dq_des_rads - dq) + qc.tau_ff_nm;
  CHECK_NEAR(t1_motor_step(&m, q, dq, 2000), expect, 1e-4);
  CHECK(m.status == 0u);
  /* Far from the target: saturates at the knee's 60 N·m, OVER_LIMIT set; clears when back inside. */
  const t1_command_t hard = {2.0f, 0.0f, 500.0f, 0.0f, 0.0f};
  send(&m, KNEE, hard, 3000);
  CHECK_NEAR(t1_motor_step(&m, 0.5f, 0.0f, 4000), 60.0f, 0.0);
  CHECK(m.status & T1_STATUS_OVER_LIMIT);
  t1_motor_step(&m, 1.99f, 0.0f, 5000);
  CHECK(!(m.status & T1_STATUS_OVER_LIMIT));
  /* Per-joint limit, not per class: ankle roll clamps at 15 although its class range is ±20. */
  t1_motor_t a;
  t1_motor_init(&a, ANKLE_ROLL);
  send(&a, ANKLE_ROLL, (t1_command_t){0.0f, 0.0f, 0.0f, 0.0f, -19.0f}, 0);
  CHECK_NEAR(t1_motor_step(&a, 0.0f, 0.0f, 1000), -15.0f, 0.0);
}

static void test_watchdog(void) {
  t1_motor_t m;
  t1_motor_init(&m, HIP);
  const t1_command_t c = {0.2f, 0.0f, 100.0f, 1.0f, 0.0f};
  const uint64_t t0 = 1000000;
  send(&m, HIP, c, t0);
  const t1_command_t qc = quantised(HIP, c);
  const float q = 0.1f, dq = 1.5f;
  const float pd = qc.kp_nm_per_rad * (qc.q_des_rad - q) + qc.kd_nms_per_rad * (qc.dq_des_rads - dq) + qc.tau_ff_nm;
  /* Still following at 49.998 ms and at exactly 50 ms. */
  CHECK_NEAR(t1_motor_step(&m, q, dq, t0 + 49998), pd, 1e-4);
  CHECK_NEAR(t1_motor_step(&m, q, dq, t0 + T1_WATCHDOG_US), pd, 1e-4);
  CHECK(!(m.status & T1_STATUS_WATCHDOG));
  /* 1 µs later: damping, kp = 0. */
  CHECK_NEAR(t1_motor_step(&m, q, dq, t0 + T1_WATCHDOG_US + 1), -T1_MOTORS[HIP].d_safe_nms * dq, 1e-5);
  CHECK(m.status & T1_STATUS_WATCHDOG);
  CHECK(m.status & T1_STATUS_DAMPING);
  /* Stays damping without a command... */
  CHECK_NEAR(t1_motor_step(&m, q, dq, t0 + 200000), -T1_MOTORS[HIP].d_safe_nms * dq, 1e-5);
  /* ...and a malformed frame does not revive it. */
  uint8_t frame[8] = {0};
  CHECK(t1_motor_receive(&m, T1_CMD_CAN_ID(HIP), frame, 5, t0 + 201000) == T1_ERR_BAD_DLC);
  t1_motor_step(&m, q, dq, t0 + 202000);
  CHECK(m.status & T1_STATUS_WATCHDOG);
  /* A fresh valid command clears WATCHDOG at once. */
  send(&m, HIP, c, t0 + 204000);
  CHECK(!(m.status & T1_STATUS_WATCHDOG));
  CHECK_NEAR(t1_motor_step(&m, q, dq, t0 + 206000), pd, 1e-4);
  CHECK(m.status == 0u);
  /* A clock that goes backwards counts as a timeout (fail safe). */
  t1_motor_step(&m, q, dq, t0);
  CHECK(m.status & T1_STATUS_WATCHDOG);
}

static void test_soft_stops(void) {
  t1_motor_t m;
  t1_motor_init(&m, KNEE);
  send(&m, KNEE, (t1_command_t){0.0f, 0.0f, 0.0f, 0.0f, 0.0f}, 0); /* zero gains: only the stop acts */
  const t1_motor_info_t* k = &T1_MOTORS[KNEE];
  const float k_stop = k->torque_limit_nm / T1_SOFT_STOP_FULL_TORQUE_RAD;
  const t1_command_t qc = quantised(KNEE, (t1_command_t){0.0f, 0.0f, 0.0f, 0.0f, 0.0f});
  /* 0.02 rad beyond q_max, moving further out at 0.5 rad/s: spring + damper push back. */
  float tau = t1_motor_step(&m, k->q_max_rad + 0.02f, 0.5f, 1000);
  CHECK_NEAR(tau, qc.tau_ff_nm - k_stop * 0.02f - k->d_safe_nms * 0.5f, 1e-3);
  CHECK(tau < 0.0f);
  CHECK(m.status & T1_STATUS_OVER_LIMIT);
  /* Returning inward: the damper does not fight the return. */
  tau = t1_motor_step(&m, k->q_max_rad + 0.02f, -0.5f, 2000);
  CHECK_NEAR(tau, qc.tau_ff_nm - k_stop * 0.02f, 1e-3);
  /* Below q_min (0 for the knee): pushes up. Far beyond: clamped at the limit. */
  tau = t1_motor_step(&m, k->q_min_rad - 0.5f, 0.0f, 3000);
  CHECK_NEAR(tau, k->torque_limit_nm, 0.0);
  /* Inside the range: no stop torque, no OVER_LIMIT. */
  tau = t1_motor_step(&m, 1.0f, 0.0f, 4000);
  CHECK_NEAR(tau, qc.tau_ff_nm, 1e-6);
  CHECK(!(m.status & T1_STATUS_OVER_LIMIT));
  /* The stop also acts in damping (power-on) mode. */
  t1_motor_t p;
  t1_motor_init(&p, KNEE);
  CHECK(t1_motor_step(&p, -0.05f, 0.0f, 0) > 0.0f);
  CHECK(p.status & T1_STATUS_OVER_LIMIT);
}

static void test_bad_frames(void) {
  t1_motor_t m;
  t1_motor_init(&m, HIP);
  const t1_command_t c = {0.3f, 0.0f, 50.0f, 1.0f, 0.0f};
  send(&m, HIP, c, 0);
  const t1_command_t before = m.command;
  uint8_t garbage[8] = {0xFF, 0x00, 0xFF, 0x00, 0xFF, 0x00, 0xFF, 0x00};
  /* Wrong DLC, wrong id (another motor's command, a reply id, an extended-range id), NULL data. */
  CHECK(t1_motor_receive(&m, T1_CMD_CAN_ID(HIP), garbage, 7, 1000) == T1_ERR_BAD_DLC);
  CHECK(m.status & T1_STATUS_BAD_FRAME);
  CHECK(t1_motor_receive(&m, T1_CMD_CAN_ID(HIP + 1), garbage, 8, 1000) == T1_ERR_BAD_ID);
  CHECK(t1_motor_receive(&m, T1_REPLY_CAN_ID(HIP), garbage, 8, 1000) == T1_ERR_BAD_ID);
  CHECK(t1_motor_receive(&m, 0x1FFFFFFFu, garbage, 8, 1000) == T1_ERR_BAD_ID);
  CHECK(t1_motor_receive(&m, T1_CMD_CAN_ID(HIP), NULL, 8, 1000) == T1_ERR_NULL);
  CHECK(t1_motor_receive(&m, T1_CMD_CAN_ID(HIP), garbage, 255, 1000) == T1_ERR_BAD_DLC);
  /* The previous command stays in force and BAD_FRAME is latched across steps. */
  CHECK(memcmp(&before, &m.command, sizeof before) == 0);
  t1_motor_step(&m, 0.3f, 0.0f, 2000);
  CHECK(m.status & T1_STATUS_BAD_FRAME);
  t1_motor_step(&m, 0.3f, 0.0f, 4000);
  CHECK(m.status & T1_STATUS_BAD_FRAME);
  uint8_t reply[8];
  CHECK(t1_motor_reply(&m, 0.3f, 0.0f, 0.0f, reply) == T1_REPLY_DLC);
  CHECK(reply[6] & T1_STATUS_BAD_FRAME);
  CHECK(reply[0] == HIP + 1 && reply[7] == 0u);
  /* Any 8 bytes on the right id decode to finite values (fixed point cannot encode NaN): accepted. */
  CHECK(t1_motor_receive(&m, T1_CMD_CAN_ID(HIP), garbage, 8, 5000) == T1_OK);
  CHECK(!(m.status & T1_STATUS_BAD_FRAME));
  CHECK(isfinite(t1_motor_step(&m, 0.0f, 0.0f, 6000)));
}

static void test_bad_sensor(void) {
  t1_motor_t m;
  t1_motor_init(&m, HIP);
  send(&m, HIP, (t1_command_t){0.3f, 0.0f, 50.0f, 1.0f, 2.0f}, 0);
  CHECK(t1_motor_step(&m, NAN, 0.0f, 1000) == 0.0f);
  CHECK(m.status & T1_STATUS_BAD_SENSOR);
  CHECK(t1_motor_step(&m, 0.0f, INFINITY, 1000) == 0.0f);
  /* Huge but finite inputs: clamped, never NaN. */
  const float tau = t1_motor_step(&m, 3e38f, -3e38f, 1000);
  CHECK(isfinite(tau) && fabsf(tau) <= T1_MOTORS[HIP].torque_limit_nm);
  t1_motor_step(&m, 0.3f, 0.0f, 2000);
  CHECK(!(m.status & T1_STATUS_BAD_SENSOR));
}

int main(void) {
  test_power_on_damping();
  test_pd_formula_and_clamp();
  test_watchdog();
  test_soft_stops();
  test_bad_frames();
  test_bad_sensor();
  return t1_test_report("test_motor");
}
