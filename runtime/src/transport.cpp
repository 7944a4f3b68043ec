#include "t1rt/transport.hpp"

#include <cstdlib>

#include "t1_contract.hpp"
#include "t1rt/composite.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/safety.hpp"

namespace t1rt {

namespace {
constexpr double kUsToS = 1e-6;
constexpr double kNsToS = 1e-9;
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
                        bool subscribe_sim_status) {
  clock_ = clock;
  supervisor_ = supervisor;
  buffer_.assign(kEncodeBufferBytes, 0);
  lcm_ = lcm_create(url.c_str());
  if (!lcm_) {
    *error = "lcm_create failed for URL '" + url + "' (multicast route missing? run inside tools/netns)";
    return false;
  }
  lcm_subscribe(lcm_, t1::CH_IMU, &LcmTransport::on_imu, this);
  lcm_subscribe(lcm_, t1::CH_JOINT_STATE, &LcmTransport::on_joint, this);
  lcm_subscribe(lcm_, t1::CH_JOYSTICK, &LcmTransport::on_joystick, this);
  lcm_subscribe(lcm_, t1::CH_RUNTIME_CMD, &LcmTransport::on_command, this);
  if (subscribe_sim_status) {
    // Decoding assigns the three strings; with this capacity (>= any accepted datagram) it never allocates.
    for (std::string* s : {&sim_status.msg.scenario, &sim_status.msg.clock, &sim_status.msg.active_faults})
      s->reserve(kSimStatusMaxBytes);
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
                                        : static_cast<double>(monotonic_ns()) * kNsToS;
}

void LcmTransport::on_imu(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (self->imu.msg.decode(rbuf->data, 0, rbuf->data_size) < 0) {
    ++self->decode_errors;
    return;
  }
  self->imu.have = true;
  self->imu.stamp_s = self->stamp(self->imu.msg.utime);
  ++self->imu.received;
  if (self->supervisor_) self->supervisor_->note_imu_seq(self->imu.msg.seq);
}

void LcmTransport::on_joint(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (self->joint.msg.decode(rbuf->data, 0, rbuf->data_size) < 0) {
    ++self->decode_errors;
    return;
  }
  self->joint.have = true;
  self->joint.stamp_s = self->stamp(self->joint.msg.utime);
  ++self->joint.received;
  self->new_joint_state = true;
  if (self->supervisor_) self->supervisor_->note_joint_seq(self->joint.msg.seq);
}

void LcmTransport::on_joystick(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (self->joystick.msg.decode(rbuf->data, 0, rbuf->data_size) < 0) {
    ++self->decode_errors;
    return;
  }
  self->joystick.have = true;
  self->joystick.stamp_s = self->stamp(self->joystick.msg.utime);
  ++self->joystick.received;
}

void LcmTransport::on_sim_status(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (rbuf->data_size > kSimStatusMaxBytes) {
    ++self->sim_status_oversized;
    return;
  }
  if (self->sim_status.msg.decode(rbuf->data, 0, rbuf->data_size) < 0) {
    ++self->decode_errors;
    return;
  }
  self->sim_status.have = true;
  self->sim_status.stamp_s = self->stamp(self->sim_status.msg.utime);
  ++self->sim_status.received;
}

void LcmTransport::on_command(const lcm_recv_buf_t* rbuf, const char*, void* p) {
  auto* self = static_cast<LcmTransport*>(p);
  if (self->command_count >= kCommandQueue) {
    ++self->commands_dropped;
    return;
  }
  if (self->commands[self->command_count].decode(rbuf->data, 0, rbuf->data_size) < 0) {
    ++self->decode_errors;
    return;
  }
  ++self->command_count;
}

}  // namespace t1rt
