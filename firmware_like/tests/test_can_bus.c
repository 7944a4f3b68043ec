/* CAN bus model tests: CRC-15 check value, bit counting against hand-computed frames, LATE detection
 * when a cycle overflows, utilisation.
 *
 * Worked example 1 (fully by hand): id 0x000, DLC 0.
 *   SOF..DLC = 1 + 11 + 3 + 4 = 19 dominant (0) bits; no data. The CRC register starts at 0 and only
 *   zeros go in, so CRC = 0x0000: 15 more zeros → 34 zeros in the stuffed region. A stuff bit (1)
 *   follows every 5 equal bits, and each stuff bit starts a new run, so zeros are stuffed after the
 *   5th, 10th, ... 30th original bit: 6 stuff bits.
 *     stuffed: 00000 1 00000 1 00000 1 00000 1 00000 1 00000 1 0000
 *   Total = 34 + 6 + CRC delimiter 1 + ACK slot 1 + ACK delimiter 1 + EOF 7 + IFS 3 = 53 bits.
 *
 * Worked example 2: command to motor 1, id 0x101, DLC 8, data all zero (q, dq, tau at the low edge,
 *   gains 0). Unstuffed SOF..data (83 bits):
 *     0 00100000001 000 1000 + 64 × 0
 *   CRC-15 (poly 0x4599) over those 83 bits = 0x3FB3 = 011111110110011 (from an independent bit-level
 *   reference in Python, and this file's check of the CRC implementation on "123456789" = 0x059E, the
 *   catalogued CRC-15/CAN check value). Stuffed region, stuff bits in brackets:
 *     000100000[1]001000100000[1]00000[1]00000[1]00000[1]00000[1]00000[1]00000[1]00000[1]00000[1]
 *     00000[1]00000[1]00000[1]00000[1]00011111[0]110110011
 *   15 stuff bits: 98 + 15 + 13 = 126 bits (an 8-byte frame without any stuffing is 111 bits).
 *
 * Overflow: 1 Mbit/s × 2 ms = 2000 bits per cycle. 15 frames of 126 bits = 1890 fit; the 16th ends at
 * bit 2016 and is LATE. 16 frames per cycle is the arms bus's load (8 commands + 8 replies); its real
 * replies are 7-byte frames, so it normally fits (about 0.91–0.94 of the cycle), with little margin.
 */
#include <string.h>

#include "t1_firmware.h"
#include "t1_test.h"

static void test_crc15_check_value(void) {
  const char* msg = "123456789";
  uint8_t bits[72];
  size_t n = 0;
  for (size_t i = 0; i < strlen(msg); ++i)
    for (int b = 7; b >= 0; --b) bits[n++] = (uint8_t)(((unsigned char)msg[i] >> b) & 1u);
  CHECK(t1_can_crc15_bits(bits, n) == 0x059Eu);
}

static void test_worked_examples(void) {
  CHECK(t1_can_stuff_bits(0x000u, NULL, 0) == 6u);
  CHECK(t1_can_frame_bits(0x000u, NULL, 0) == 53u);

  const uint8_t zeros[8] = {0};
  CHECK(t1_can_stuff_bits(0x101u, zeros, 8) == 15u);
  CHECK(t1_can_frame_bits(0x101u, zeros, 8) == 126u);

  /* Reply of motor 5 (id 0x205, DLC 7) {05 80 00 80 08 00 10}: 90 unstuffed bits, CRC 0x4BCA,
   * 9 stuff bits (independent reference) → 90 + 9 + 13 = 112. */
  const uint8_t reply[7] = {0x05, 0x80, 0x00, 0x80, 0x08, 0x00, 0x10};
  CHECK(t1_can_stuff_bits(0x205u, reply, 7) == 9u);
  CHECK(t1_can_frame_bits(0x205u, reply, 7) == 112u);

  /* Bounds: no frame is shorter than its unstuffed length or longer than the worst stuffing. */
  uint8_t data[8];
  for (unsigned seed = 1; seed < 2000; ++seed) {
    for (int i = 0; i < 8; ++i) data[i] = (uint8_t)((seed * 2654435761u) >> (i * 3));
    const uint32_t bits = t1_can_frame_bits(0x100u + (seed % 0x100u), data, 8);
    CHECK(bits >= 111u && bits <= 111u + 24u);
  }
  /* Invalid id or DLC → 0 bits (not a frame). */
  CHECK(t1_can_frame_bits(0x800u, zeros, 8) == 0u);
  CHECK(t1_can_frame_bits(0x101u, zeros, 9) == 0u);
}

/* Bit-level reference (the textbook algorithm, one bit at a time over an explicit bit array) to check
 * the library's byte-table implementation on many frames. */
static uint32_t reference_frame_bits(uint32_t id, const uint8_t* data, uint8_t dlc) {
  uint8_t bits[128];
  size_t n = 0;
  bits[n++] = 0;
  for (int b = 10; b >= 0; --b) bits[n++] = (uint8_t)((id >> b) & 1u);
  bits[n++] = 0;
  bits[n++] = 0;
  bits[n++] = 0;
  for (int b = 3; b >= 0; --b) bits[n++] = (uint8_t)((dlc >> b) & 1u);
  for (int i = 0; i < dlc; ++i)
    for (int b = 7; b >= 0; --b) bits[n++] = (uint8_t)((data[i] >> b) & 1u);
  const uint16_t crc = t1_can_crc15_bits(bits, n);
  for (int b = 14; b >= 0; --b) bits[n++] = (uint8_t)((crc >> b) & 1u);
  uint32_t stuff = 0, run = 0;
  int value = -1;
  for (size_t i = 0; i < n; ++i) {
    if (bits[i] == value) {
      ++run;
    } else {
      value = bits[i];
      run = 1;
    }
    if (run == 5) {
      ++stuff;
      value ^= 1;
      run = 1;
    }
  }
  return (uint32_t)n + stuff + 13u;
}

static void test_against_bit_reference(void) {
  uint32_t x = 12345u;
  int mismatches = 0;
  for (int k = 0; k < 20000; ++k) {
    uint8_t data[8];
    for (int i = 0; i < 8; ++i) {
      x = x * 1103515245u + 12345u;
      /* Mix of random bytes and long runs (0x00 / 0xFF), where stuffing matters most. */
      data[i] = (x >> 28) < 4u ? (uint8_t)((x >> 27) & 1u ? 0xFFu : 0x00u) : (uint8_t)(x >> 16);
    }
    const uint32_t id = (x >> 5) & 0x7FFu;
    const uint8_t dlc = (uint8_t)(k % 9);
    if (t1_can_frame_bits(id, data, dlc) != reference_frame_bits(id, data, dlc)) ++mismatches;
  }
  CHECK(mismatches == 0);
}

static void test_late_detection(void) {
  t1_bus_t bus;
  CHECK(t1_bus_init(&bus, T1_BUS_ARMS, T1_BUS_BITRATE_BPS, T1_BUS_CYCLE_US) == T1_OK);
  CHECK(bus.capacity_bits == 2000u);
  const uint8_t zeros[8] = {0};
  t1_bus_begin_cycle(&bus, 0);
  for (int k = 0; k < 15; ++k) CHECK(t1_bus_submit(&bus, 0x101u, zeros, 8) == T1_BUS_ON_TIME);
  CHECK(bus.bits_this_cycle == 1890u);
  CHECK(t1_bus_submit(&bus, 0x101u, zeros, 8) == T1_BUS_LATE);
  CHECK(bus.late_this_cycle == 1u && bus.frames_late_total == 1u);
  /* The next cycle starts empty; utilisation reports the completed (overloaded) one. */
  t1_bus_begin_cycle(&bus, 2000);
  CHECK_NEAR(t1_bus_utilisation(&bus), 2016.0 / 2000.0, 1e-6);
  CHECK(bus.late_this_cycle == 0u && bus.bits_this_cycle == 0u);
  CHECK(t1_bus_submit(&bus, 0x101u, zeros, 8) == T1_BUS_ON_TIME);
  CHECK(t1_bus_submit(&bus, 0x900u, zeros, 8) < 0);
  CHECK(t1_bus_submit(&bus, 0x101u, zeros, 9) == T1_ERR_BAD_DLC);
  CHECK(t1_bus_init(&bus, 4, T1_BUS_BITRATE_BPS, T1_BUS_CYCLE_US) == T1_ERR_BAD_INDEX);
}

/* A realistic cycle through the batch helper: every motor commanded and replying. */
static void test_batch_cycle(void) {
  t1_bus_array_t buses;
  t1_motor_array_t motors;
  CHECK(t1_bus_array_init(&buses) == T1_OK);
  t1_motor_array_init(&motors);
  double zero[T1_NUM_MOTORS] = {0}, kp[T1_NUM_MOTORS], kd[T1_NUM_MOTORS];
  for (int i = 0; i < T1_NUM_MOTORS; ++i) {
    kp[i] = 30.0;
    kd[i] = 2.0;
  }
  uint8_t cmds[T1_NUM_MOTORS * 8], replies[T1_NUM_MOTORS * 8], cmd_ok[T1_NUM_MOTORS], rep_ok[T1_NUM_MOTORS];
  CHECK(t1_batch_pack_commands(zero, zero, kp, kd, zero, cmds) == 0u);
  CHECK(t1_batch_receive(&motors, cmds, (1u << T1_NUM_MOTORS) - 1u, 0) == 0u);
  double tau[T1_NUM_MOTORS];
  t1_batch_step(&motors, zero, zero, 0, tau);
  t1_batch_replies(&motors, zero, zero, tau, replies);
  t1_batch_bus_cycle(&buses, 0, cmds, (1u << T1_NUM_MOTORS) - 1u, replies, cmd_ok, rep_ok);
  for (int i = 0; i < T1_NUM_MOTORS; ++i) CHECK(cmd_ok[i] == 1u);
  for (int k = 0; k < T1_NUM_BUSES; ++k) {
    printf("bus %d (%s): %u frames, %u bits of %u\n", k, T1_BUS_NAMES[k], buses.buses[k].frames_this_cycle,
           buses.buses[k].bits_this_cycle, buses.buses[k].capacity_bits);
  }
  CHECK(buses.buses[T1_BUS_HEAD_WAIST].frames_this_cycle == 6u);
  CHECK(buses.buses[T1_BUS_ARMS].frames_this_cycle == 16u);
}

int main(void) {
  test_crc15_check_value();
  test_worked_examples();
  test_against_bit_reference();
  test_late_detection();
  test_batch_cycle();
  return t1_test_report("test_can_bus");
}
