/* libFuzzer harness: CAN reply frames as the host receives them, through the simulator's in-process buses.
 * Input: 23 reply slots of 8 bytes (what the motors put on the wire), then the masks of one cycle:
 * send, drop (4 bytes each, LE), delay cycles (1 byte), a dlc for the single-frame decoder (1 byte).
 * Path: t1_link_send_commands / t1_link_exchange_replies (bus model, late and delayed FIFOs) ->
 * t1_host_view_update (t1_unpack_reply per slot, NaN + NO_REPLY status for what does not decode) and
 * t1_batch_unpack_replies; each slot also through t1_unpack_reply with the fuzzed dlc. A decoded reading is
 * always finite. Three cycles run per input, so late and delayed frames are carried over. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "t1_firmware.h"

#define SLOTS_BYTES (T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES)

static uint32_t u32_at(const uint8_t* p) {
  return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static t1_link_t link; /* ~50 kB: static, re-initialised for each input */
  static t1_motor_array_t motors;
  uint8_t replies[SLOTS_BYTES], commands[SLOTS_BYTES], host[SLOTS_BYTES];
  double q[T1_NUM_MOTORS], dq[T1_NUM_MOTORS], tau[T1_NUM_MOTORS];
  int32_t status[T1_NUM_MOTORS];
  uint32_t send_mask, drop_mask, delay, got, bad;
  uint8_t dlc;
  if (size < SLOTS_BYTES + 10) return 0;
  memcpy(replies, data, SLOTS_BYTES);
  send_mask = u32_at(data + SLOTS_BYTES);
  drop_mask = u32_at(data + SLOTS_BYTES + 4);
  delay = data[SLOTS_BYTES + 8] % 4u;
  dlc = data[SLOTS_BYTES + 9];
  if (t1_link_init(&link) != T1_OK) __builtin_trap();
  t1_motor_array_init(&motors);
  memset(commands, 0, sizeof(commands));
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) q[i] = dq[i] = tau[i] = 0.0, status[i] = 0;
  for (uint64_t cycle = 0; cycle < 3; ++cycle) {
    (void)t1_link_send_commands(&link, &motors, 1000 + cycle * 2000, commands, send_mask, drop_mask, delay, 0);
    got = t1_link_exchange_replies(&link, replies, send_mask, drop_mask, host);
    t1_host_view_update(host, got, q, dq, tau, status);
    send_mask = ~send_mask;
  }
  bad = t1_batch_unpack_replies(replies, q, dq, tau, status);
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    t1_reply_t r;
    if (!(bad & (1u << i)) && !(isfinite(q[i]) && isfinite(dq[i]) && isfinite(tau[i]))) __builtin_trap();
    if (t1_unpack_reply(replies + i * T1_FRAME_SLOT_BYTES, dlc > T1_FRAME_SLOT_BYTES ? T1_FRAME_SLOT_BYTES : dlc, &r) ==
            T1_OK &&
        !(isfinite(r.q_rad) && isfinite(r.dq_rads) && isfinite(r.tau_nm)))
      __builtin_trap();
  }
  return 0;
}
