/* The simulator's in-process buses (t1_firmware.h, "host link"): frame for frame what sim_hil's python-can
 * MotorBus does, so the default simulator pays one call per direction per tick instead of a Python object,
 * a queue and a bus-model call per frame. */
#include <string.h>

#include "t1_firmware.h"

size_t t1_link_size(void) { return sizeof(t1_link_t); }

int t1_link_init(t1_link_t* l) {
  if (l == NULL) return T1_ERR_NULL;
  memset(l, 0, sizeof(*l));
  for (unsigned k = 0; k < T1_NUM_BUSES; ++k) {
    const int rc = t1_bus_init(&l->buses[k], k, T1_BUS_BITRATE_BPS, T1_BUS_CYCLE_US);
    if (rc != T1_OK) return rc;
  }
  return T1_OK;
}

static int is_command_id(uint32_t can_id) {
  return can_id > T1_CMD_ID_BASE && can_id <= T1_CMD_ID_BASE + T1_NUM_MOTORS;
}

/* Submit to the frame's bus: on time → it reaches the far end's receive slot; late → carried to the head
 * of the next cycle. */
static void put_on_wire(t1_link_t* l, const t1_link_frame_t* f) {
  t1_bus_t* bus = &l->buses[f->bus];
  if (t1_bus_submit(bus, f->can_id, f->data, f->dlc) != T1_BUS_ON_TIME) {
    if (l->n_late[f->bus] < T1_LINK_LATE_CAPACITY) {
      l->late[f->bus][l->n_late[f->bus]++] = *f;
    } else {
      ++l->frames_lost_overflow;
    }
    return;
  }
  ++l->frames_sent;
  const int cmd = is_command_id(f->can_id);
  const unsigned i = f->can_id - (cmd ? T1_CMD_ID_BASE : T1_REPLY_ID_BASE) - 1u;
  uint8_t* slot = (cmd ? l->motor_rx : l->host_rx) + (size_t)i * T1_FRAME_SLOT_BYTES;
  memset(slot, 0, T1_FRAME_SLOT_BYTES);
  memcpy(slot, f->data, f->dlc);
  if (cmd) {
    l->motor_rx_mask |= 1u << i;
  } else {
    l->host_rx_mask |= 1u << i;
  }
}

static void flush_late(t1_link_t* l) {
  t1_link_frame_t pending[T1_LINK_LATE_CAPACITY];
  for (unsigned k = 0; k < T1_NUM_BUSES; ++k) {
    const uint32_t n = l->n_late[k];
    memcpy(pending, l->late[k], n * sizeof(pending[0]));
    l->n_late[k] = 0;
    for (uint32_t j = 0; j < n; ++j) put_on_wire(l, &pending[j]);
  }
}

static t1_link_frame_t frame_of(unsigned motor, uint32_t can_id, const uint8_t* slots, uint8_t dlc) {
  t1_link_frame_t f;
  memset(&f, 0, sizeof(f));
  f.can_id = can_id;
  f.bus = T1_MOTORS[motor].bus;
  f.dlc = dlc;
  memcpy(f.data, slots + (size_t)motor * T1_FRAME_SLOT_BYTES, dlc);
  return f;
}

static void release_delayed(t1_link_t* l) {
  while (l->n_delayed > 0 && l->delayed[l->delayed_head].due_cycle <= l->cycle) {
    put_on_wire(l, &l->delayed[l->delayed_head]);
    l->delayed_head = (l->delayed_head + 1u) % T1_LINK_DELAY_CAPACITY;
    --l->n_delayed;
  }
}

uint32_t t1_link_send_commands(t1_link_t* l, t1_motor_array_t* motors, uint64_t now_us, const uint8_t* frames,
                               uint32_t send_mask, uint32_t drop_mask, uint32_t delay_cycles, uint32_t dead_mask) {
  if (l == NULL || motors == NULL) return 0u;
  for (unsigned k = 0; k < T1_NUM_BUSES; ++k) t1_bus_begin_cycle(&l->buses[k], now_us);
  flush_late(l);
  for (unsigned i = 0; frames != NULL && i < T1_NUM_MOTORS; ++i) {
    if (!(send_mask & (1u << i))) continue;
    if (drop_mask & (1u << i)) {
      ++l->frames_dropped;
      continue;
    }
    t1_link_frame_t f = frame_of(i, T1_CMD_CAN_ID(i), frames, T1_CMD_DLC);
    if (delay_cycles == 0u) {
      put_on_wire(l, &f);
    } else if (l->n_delayed < T1_LINK_DELAY_CAPACITY) {
      f.due_cycle = l->cycle + delay_cycles;
      l->delayed[(l->delayed_head + l->n_delayed++) % T1_LINK_DELAY_CAPACITY] = f;
    } else {
      ++l->frames_lost_overflow;
    }
  }
  release_delayed(l);
  const uint32_t deliver = l->motor_rx_mask & ~dead_mask;
  l->motor_rx_mask = 0u;
  if (deliver == 0u) return 0u;
  return deliver & ~t1_batch_receive(motors, l->motor_rx, deliver, now_us);
}

uint32_t t1_link_exchange_replies(t1_link_t* l, const uint8_t* replies, uint32_t send_mask, uint32_t drop_mask,
                                  uint8_t* host_frames) {
  if (l == NULL || replies == NULL || host_frames == NULL) return 0u;
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    if (!(send_mask & (1u << i))) continue;
    if (drop_mask & (1u << i)) {
      ++l->frames_dropped;
      continue;
    }
    const t1_link_frame_t f = frame_of(i, T1_REPLY_CAN_ID(i), replies, T1_REPLY_DLC);
    put_on_wire(l, &f);
  }
  const uint32_t got = l->host_rx_mask;
  memcpy(host_frames, l->host_rx, sizeof(l->host_rx));
  l->host_rx_mask = 0u;
  ++l->cycle;
  return got;
}

void t1_link_counters(const t1_link_t* l, uint64_t out[3]) {
  if (l == NULL || out == NULL) return;
  out[0] = l->frames_sent;
  out[1] = l->frames_dropped;
  out[2] = l->frames_lost_overflow;
}

void t1_host_view_update(const uint8_t* host_frames, uint32_t got, double* q, double* dq, double* tau,
                         int32_t* status) {
  if (host_frames == NULL || q == NULL || dq == NULL || tau == NULL || status == NULL) return;
  double rq[T1_NUM_MOTORS], rdq[T1_NUM_MOTORS], rtau[T1_NUM_MOTORS];
  int32_t rstatus[T1_NUM_MOTORS];
  (void)t1_batch_unpack_replies(host_frames, rq, rdq, rtau, rstatus);
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    if (got & (1u << i)) {
      q[i] = rq[i];
      dq[i] = rdq[i];
      tau[i] = rtau[i];
      status[i] = rstatus[i];
    } else {
      status[i] = (int32_t)((uint32_t)status[i] | T1_STATUS_NO_REPLY);
    }
  }
}
