#include "t1rt/transport.hpp"

#include <cstdlib>
#include <utility>

#include "t1_contract.hpp"
#include "t1rt/composite.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/safety.hpp"

namespace t1rt {

namespace {
constexpr double kUsToS = 1e-6;
}  // namespace

const char* clock_name(ClockMode mode) { return mode == ClockMode::kLockstep ? "lockstep" : "realtime"; }

std::string resolve_lcm_url(const std::string& cli_url) {
  if (!cli_url.empty()) return cli_url;
  const char* env = std::getenv("T1_LCM_URL");
  if (env && *env) return env;
  return t1::kDefaultLcmUrl;
}

LcmTransport::~LcmTransport() {
  if (lcm_) lcm_destroy(lcm_);
}

bool LcmTransport::open(const std::string& url, ClockMode clock, Supervisor* supervisor, std::string* error,
                        bool subscribe_sim_status, bool subscribe_robot_state) {
  clock_ = clock;
  supervisor_ = supervisor;
  buffer_.assign(kEncodeBufferBytes, 0);
  lcm_ = lcm_create(url.c_str());
  if (!lcm_) {
    *error = "lcm_create failed for URL '" + url + "' (multicast route missing? run inside tools/netns)";
    return false;
  }
  if (subscribe_robot_state) {
    lcm_subscribe(lcm_, t1::CH_IMU, &LcmTransport::on_imu, this);
    lcm_subscribe(lcm_, t1::CH_JOINT_STATE, &LcmTransport::on_joint, this);
  }
  lcm_subscribe(lcm_, t1::CH_JOYSTICK, &LcmTransport::on_joystick, this);
  lcm_subscribe(lcm_, t1::CH_RUNTIME_CMD, &LcmTransport::on_command, this);
  if (subscribe_sim_status) {
    // Decoding assigns the three strings; with this capacity (>= any accepted datagram) it never allocates.
    for (t1::sim_status_t* m : {&sim_status.msg, &sim_status.scratch})
      for (std::string* s : {&m->scenario, &m->clock, &m->active_faults}) s->reserve(kSimStatusMaxBytes);
    lcm_subscribe(lcm_, t1::CH_SIM_STATUS, &LcmTransport::on_sim_status, this);
  }
  return true;
}

int LcmTransport::handle(int timeout_ms) { return lcm_handle_timeout(lcm_, timeout_ms); }

void LcmTransport::drain() {
  while (lcm_handle_timeout(lcm_, 0) > 0) {
  }
}

double LcmTransport::stamp(int64_t utime) const {
  return clock_ == ClockMode::kLockstep ? static_cast<double>(utime) * kUsToS
                                        : monotonic_s();
}

// Safety rule R3 (src/safety_supervisor.cpp): decode into scratch; only a datagram that decodes exactly
// (no error, no trailing bytes) may replace the live message.
template <class Message>
bool LcmTransport::decode_scratch(MessageSlot<Message>& slot, const lcm_recv_buf_t* rbuf) {
  const int used = slot.scratch.decode(rbuf->data, 0, rbuf->data_size);
  if (used < 0 || static_cast<uint32_t>(used) != rbuf->data_size) {
    ++decode_errors;
    return false;
  }
  return true;
}

template <class Message>
void LcmTransport::commit(MessageSlot<Message>& slot) {
  std::swap(slot.msg, slot.scratch);  // fixed-size messages copy; sim_status_t strings swap buffers
  slot.have = true;
  slot.stamp_s = stamp(slot.msg.utime);
  ++slot.received;
}

void LcmTransport::on_imu(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (!self->decode_scratch(self->imu, rbuf)) return;
  if (self->supervisor_ && !self->supervisor_->accept_imu_seq(self->imu.scratch.seq)) return;
  self->commit(self->imu);
}

void LcmTransport::on_joint(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (!self->decode_scratch(self->joint, rbuf)) return;
  if (self->supervisor_ && !self->supervisor_->accept_joint_seq(self->joint.scratch.seq)) return;
  self->commit(self->joint);
  self->new_joint_state = true;
}

void LcmTransport::on_joystick(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (self->decode_scratch(self->joystick, rbuf)) self->commit(self->joystick);
}

void LcmTransport::on_sim_status(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (rbuf->data_size > kSimStatusMaxBytes) {
    ++self->sim_status_oversized;
    return;
  }
  if (self->decode_scratch(self->sim_status, rbuf)) self->commit(self->sim_status);
}

void LcmTransport::on_command(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  t1::runtime_cmd_t& c = self->command_scratch_;
  const int used = c.decode(rbuf->data, 0, rbuf->data_size);
  if (used < 0 || static_cast<uint32_t>(used) != rbuf->data_size) {
    ++self->decode_errors;
    return;
  }
  if (c.verb == "estop") {  // safety rule R2: outside the bounded queue
    self->estop_pending = true;
    return;
  }
  if (self->command_count >= kCommandQueue) {
    ++self->commands_dropped;
    return;
  }
  std::swap(self->commands[self->command_count++], c);
}

}  // namespace t1rt
