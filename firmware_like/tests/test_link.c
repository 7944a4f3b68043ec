/* Host link tests: a normal cycle delivers every command and reply on time; lost frames never arrive;
 * a delayed command reaches its motor that many cycles later; a dead motor latches nothing; frames that
 * overflow a cycle arrive at the head of the next one. */
#include <string.h>

#include "t1_firmware.h"
#include "t1_test.h"

#define ALL ((1u << T1_NUM_MOTORS) - 1u)

static t1_link_t link_;
static t1_motor_array_t motors;
static uint8_t commands[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES];
static uint8_t replies[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES];
static uint8_t host[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES];

static void setup(void) {
  CHECK(t1_link_init(&link_) == T1_OK);
  t1_motor_array_init(&motors);
  double q[T1_NUM_MOTORS], zero[T1_NUM_MOTORS], kp[T1_NUM_MOTORS];
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    q[i] = 0.01 * i;
    zero[i] = 0.0;
    kp[i] = 20.0;
  }
  CHECK(t1_batch_pack_commands(q, zero, kp, zero, zero, commands) == 0u);
  t1_batch_replies(&motors, q, zero, zero, replies);
}

/* One tick at cycle k: commands (send/drop/delay/dead), then every motor replies. */
static uint32_t tick(uint32_t send, uint32_t drop, uint32_t delay, uint32_t dead, uint32_t* got) {
  const uint64_t now = (uint64_t)link_.cycle * T1_BUS_CYCLE_US;
  const uint32_t latched = t1_link_send_commands(&link_, &motors, now, commands, send, drop, delay, dead);
  *got = t1_link_exchange_replies(&link_, replies, ALL & ~dead, 0u, host);
  return latched;
}

static void test_normal_cycle(void) {
  setup();
  uint32_t got = 0;
  CHECK(tick(ALL, 0u, 0u, 0u, &got) == ALL);
  CHECK(got == ALL);
  CHECK(memcmp(host, replies, sizeof(host)) == 0);
  CHECK(link_.frames_sent == 2u * T1_NUM_MOTORS);
  for (unsigned k = 0; k < T1_NUM_BUSES; ++k) CHECK(link_.buses[k].frames_late_total == 0u);
  CHECK(motors.motors[5].has_command == 1u);
  CHECK_NEAR(motors.motors[5].command.kp_nm_per_rad, 20.0, 0.05);
}

static void test_lost_and_dead(void) {
  setup();
  uint32_t got = 0;
  const uint32_t lost = (1u << 3) | (1u << 17), dead = 1u << 9;
  CHECK(tick(ALL, lost, 0u, dead, &got) == (ALL & ~lost & ~dead));
  CHECK(got == (ALL & ~dead));
  CHECK(link_.frames_dropped == 2u);
  CHECK(motors.motors[3].has_command == 0u && motors.motors[9].has_command == 0u);
}

static void test_delay(void) {
  setup();
  uint32_t got = 0;
  CHECK(tick(ALL, 0u, 3u, 0u, &got) == 0u); /* cycle 0: held */
  CHECK(tick(0u, 0u, 0u, 0u, &got) == 0u);  /* cycles 1, 2: nothing due */
  CHECK(tick(0u, 0u, 0u, 0u, &got) == 0u);
  CHECK(tick(0u, 0u, 0u, 0u, &got) == ALL); /* cycle 3: due */
  CHECK(link_.n_delayed == 0u);
}

static void test_overflow_carries_to_next_cycle(void) {
  setup();
  uint32_t got = 0;
  /* Cycle 0's commands held 2 cycles arrive after cycle 2's own: twice the commands on every bus. */
  (void)tick(ALL, 0u, 2u, 0u, &got);
  (void)tick(0u, 0u, 0u, 0u, &got);
  (void)tick(ALL, 0u, 0u, 0u, &got);
  uint64_t late = 0, carried = 0;
  for (unsigned k = 0; k < T1_NUM_BUSES; ++k) {
    late += link_.buses[k].frames_late_total;
    carried += link_.n_late[k];
  }
  CHECK(late > 0u);
  CHECK(carried == late); /* every late frame waits for the next cycle, none lost */
  CHECK(got != ALL);      /* late replies: missing this cycle ... */
  (void)tick(0u, 0u, 0u, 0u, &got);
  CHECK(got == ALL); /* ... and on the host the cycle after */
  for (unsigned k = 0; k < T1_NUM_BUSES; ++k) CHECK(link_.n_late[k] == 0u);
  CHECK(link_.frames_lost_overflow == 0u);
}

int main(void) {
  test_normal_cycle();
  test_lost_and_dead();
  test_delay();
  test_overflow_carries_to_next_cycle();
  return t1_test_report("test_link");
}
