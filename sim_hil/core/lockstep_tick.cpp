// The C API of the simulator's core (bound by sim_hil/tick_core.py): the LCM robot link, and one control
// tick of sim_hil/sim.py's Simulator.tick in a single call: publish state k, wait for the command answering
// it, put it on the buses (firmware_like's host link), step the firmware motors and MuJoCo, read the reply
// frames into the host's joint view. The simulator takes this path whenever a tick needs nothing that lives
// in Python (no IMU noise or bias, no frozen encoder, no push due, no viewer); the Python tick is the
// reference it is tested against, bit for bit.
#include <cmath>
#include <cstring>
#include <new>

#include <mujoco/mujoco.h>

#include "robot_link.hpp"

using t1sim::RobotLink;

extern "C" {

typedef void (*t1_mj_step_fn)(const mjModel*, mjData*);

// Everything one tick touches; pointers stay valid between ticks (owned by the Python simulator).
typedef struct {
  const mjModel* model;
  mjData* data;
  t1_mj_step_fn mj_step;
  t1_link_t* buses;
  t1_motor_array_t* motors;
  double *host_q, *host_dq, *host_tau;  // the host's joint view (sim_hil.firmware.HostView)
  int32_t* host_status;
  int substeps;
  int quat_adr, gyro_adr, accel_adr;  // the IMU's sensordata addresses
} t1_sim_plant;

typedef struct {             // this tick's faults (all zero: none)
  uint32_t dead_mask;        // motors off the bus: no frames, no torque
  uint32_t cmd_drop_mask;    // command frames lost on the wire
  uint32_t reply_drop_mask;  // reply frames lost on the wire
  uint32_t delay_cycles;     // command frames held this many bus cycles
} t1_sim_tick_faults;

RobotLink* t1_sim_link_open(const char* url) {
  auto* link = new (std::nothrow) RobotLink(url);
  if (link != nullptr && !link->good()) {
    delete link;
    return nullptr;
  }
  return link;
}

void t1_sim_link_close(RobotLink* link) { delete link; }

// 1: the link signs its state from now on as sender_id with this key (messages/auth.py); 0: OpenSSL refused.
int t1_sim_link_set_robot_key(RobotLink* link, int64_t sender_id, const uint8_t* key, int size) {
  return size > 0 && link->set_robot_key(sender_id, key, static_cast<std::size_t>(size)) ? 1 : 0;
}

int t1_sim_link_publish(RobotLink* link, const char* channel, const void* data, int size) {
  return link->publish(channel, data, size);
}

void t1_sim_link_publish_state(RobotLink* link, int64_t utime_us, int64_t seq, const double* quat, const double* gyro,
                               const double* accel, const double* q, const double* dq, const double* tau,
                               const int32_t* status) {
  link->publish_state({utime_us, seq, quat, gyro, accel, q, dq, tau, status});
}

void t1_sim_link_poll(RobotLink* link, double timeout_s) { link->poll(timeout_s); }

int t1_sim_link_wait_for_answer(RobotLink* link, int64_t state_seq, double timeout_s) {
  return link->wait_for_answer(state_seq, timeout_s) ? 1 : 0;
}

int t1_sim_link_take_frames(RobotLink* link, uint8_t* out) { return link->take_frames(out) ? 1 : 0; }

// The newest valid command's LCM payload (for Python to decode); its length, 0 if none yet, -1 if cap is short.
int t1_sim_link_latest(const RobotLink* link, uint8_t* out, int cap) {
  const auto& p = link->latest_payload();
  if (p.size() > static_cast<size_t>(cap)) return -1;
  std::memcpy(out, p.data(), p.size());
  return static_cast<int>(p.size());
}

// counters: {received, dropped}; the last drop reason is a NUL-terminated string owned by the link.
void t1_sim_link_counters(const RobotLink* link, uint64_t* out) {
  out[0] = link->received;
  out[1] = link->dropped;
}

const char* t1_sim_link_last_drop_reason(const RobotLink* link) { return link->last_drop_reason.c_str(); }

static uint64_t now_us(const mjData* d) { return static_cast<uint64_t>(std::llround(d->time * 1e6)); }

// One lockstep tick k = seq. Returns 1 if the command answering state k arrived within wait_s, else 0 (the
// motors keep their last command and their watchdog decides).
int t1_sim_lockstep_tick(RobotLink* link, const t1_sim_plant* p, const t1_sim_tick_faults* f, int64_t seq,
                         double wait_s) {
  mjData* d = p->data;
  const int nq_free = 7, nv_free = 6;  // the floating base's qpos / qvel entries come first
  double gyro[3], accel[3];            // + 0.0 as the Python tick's zero bias: a -0.0 reading is published as 0.0
  for (int i = 0; i < 3; ++i) {
    gyro[i] = d->sensordata[p->gyro_adr + i] + 0.0;
    accel[i] = d->sensordata[p->accel_adr + i] + 0.0;
  }
  link->publish_state({static_cast<int64_t>(now_us(d)), seq, d->sensordata + p->quat_adr, gyro, accel, p->host_q,
                       p->host_dq, p->host_tau, p->host_status});
  const int answered = link->wait_for_answer(seq, wait_s) ? 1 : 0;

  uint8_t frames[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES];
  const bool fresh = link->take_frames(frames);
  (void)t1_link_send_commands(p->buses, p->motors, now_us(d), fresh ? frames : nullptr,
                              fresh ? (1u << T1_NUM_MOTORS) - 1u : 0u, f->cmd_drop_mask, f->delay_cycles, f->dead_mask);
  double tau[T1_NUM_MOTORS] = {};
  for (int s = 0; s < p->substeps; ++s) {
    t1_batch_step(p->motors, d->qpos + nq_free, d->qvel + nv_free, now_us(d), tau);
    for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
      if (f->dead_mask & (1u << i)) tau[i] = 0.0;
      d->ctrl[i] = tau[i];
    }
    p->mj_step(p->model, d);
  }
  uint8_t replies[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES];
  uint8_t host[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES];
  t1_batch_replies(p->motors, d->qpos + nq_free, d->qvel + nv_free, tau, replies);
  const uint32_t got = t1_link_exchange_replies(p->buses, replies, ((1u << T1_NUM_MOTORS) - 1u) & ~f->dead_mask,
                                                f->reply_drop_mask, host);
  t1_host_view_update(host, got, p->host_q, p->host_dq, p->host_tau, p->host_status);
  return answered;
}

// Ticks seq0 … seq0 + n − 1 under the same faults (the simulator batches the ticks between two things that
// need Python: a status message, a fault window's edge); returns how many were answered within wait_s.
int t1_sim_lockstep_ticks(RobotLink* link, const t1_sim_plant* p, const t1_sim_tick_faults* f, int64_t seq0, int n,
                          double wait_s) {
  int answered = 0;
  for (int i = 0; i < n; ++i) answered += t1_sim_lockstep_tick(link, p, f, seq0 + i, wait_s);
  return answered;
}

}  // extern "C"
