/* libFuzzer harness: CAN command frames as a motor driver receives them off its bus.
 * Input: a run of frames, each 11 bytes: can_id (2 bytes LE, any 11-bit value and beyond), dlc (0..255),
 * 8 data bytes; then q, dq (2 floats) of the motor's sensors. Every frame goes to the firmware as the bus
 * delivers it (t1_bus_submit: the bit-exact frame length, stuffing and CRC-15 of the bus model) and to the
 * motor its id names (t1_motor_receive: t1_unpack_command, refusal latching BAD_FRAME), then the motor steps
 * (watchdog, gain and torque limits) and builds its reply (t1_motor_reply -> t1_pack_reply); the host decodes
 * that reply. The same 23 slots also go through the batch path the simulator uses (t1_batch_receive,
 * t1_batch_unpack_commands). */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "t1_firmware.h"

#define FRAME_BYTES 11u
#define MAX_FRAMES 64u

static float float_at(const uint8_t* p) {
  float f;
  memcpy(&f, p, sizeof(f));
  return f;
}

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  t1_motor_array_t motors;
  t1_bus_array_t buses;
  uint8_t slots[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES];
  uint32_t deliver = 0;
  size_t n = size / FRAME_BYTES;
  uint64_t now_us = 1000;
  float q = 0.0f, dq = 0.0f;
  if (n > MAX_FRAMES) n = MAX_FRAMES;
  if (size >= n * FRAME_BYTES + 8) {
    q = float_at(data + n * FRAME_BYTES);
    dq = float_at(data + n * FRAME_BYTES + 4);
  }
  t1_motor_array_init(&motors);
  if (t1_bus_array_init(&buses) != T1_OK) __builtin_trap();
  memset(slots, 0, sizeof(slots));
  t1_bus_begin_cycle(&buses.buses[0], now_us);
  for (size_t k = 0; k < n; ++k) {
    const uint8_t* f = data + k * FRAME_BYTES;
    const uint32_t can_id = (uint32_t)f[0] | ((uint32_t)f[1] << 8);
    const uint8_t dlc = f[2];
    uint8_t payload[T1_FRAME_SLOT_BYTES];
    const unsigned index = (unsigned)(can_id & 0xFFu) % T1_NUM_MOTORS;
    t1_command_t cmd;
    uint8_t reply[T1_FRAME_SLOT_BYTES];
    t1_reply_t seen;
    float tau;
    int dlc_out;
    memcpy(payload, f + 3, sizeof(payload));
    (void)t1_bus_submit(&buses.buses[index % T1_NUM_BUSES], can_id, payload, dlc);
    (void)t1_unpack_command(index, payload, dlc, &cmd);
    (void)t1_motor_receive(&motors.motors[index], can_id, payload, dlc, now_us);
    tau = t1_motor_step(&motors.motors[index], q, dq, now_us);
    if (!isfinite(tau)) __builtin_trap(); /* the firmware never applies a non-finite torque */
    dlc_out = t1_motor_reply(&motors.motors[index], q, dq, tau, reply);
    if (dlc_out == T1_REPLY_DLC && t1_unpack_reply(reply, (uint8_t)dlc_out, &seen) != T1_OK) __builtin_trap();
    memcpy(slots + index * T1_FRAME_SLOT_BYTES, payload, T1_FRAME_SLOT_BYTES);
    deliver |= 1u << index;
    now_us += 2000;
  }
  {
    double q_des[T1_NUM_MOTORS], dq_des[T1_NUM_MOTORS], kp[T1_NUM_MOTORS], kd[T1_NUM_MOTORS];
    double tau_ff[T1_NUM_MOTORS], qs[T1_NUM_MOTORS], dqs[T1_NUM_MOTORS], tau[T1_NUM_MOTORS];
    int32_t status[T1_NUM_MOTORS];
    for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) qs[i] = q, dqs[i] = dq;
    (void)t1_batch_receive(&motors, slots, deliver, now_us);
    t1_batch_unpack_commands(slots, q_des, dq_des, kp, kd, tau_ff);
    t1_batch_step(&motors, qs, dqs, now_us, tau);
    for (unsigned i = 0; i < T1_NUM_MOTORS; ++i)
      if (!isfinite(tau[i])) __builtin_trap();
    t1_batch_status(&motors, status);
  }
  return 0;
}
