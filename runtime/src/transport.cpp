#include "t1rt/transport.hpp"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "t1_contract.hpp"
#include "t1_lcm_group.hpp"
#include "t1rt/command_auth.hpp"
#include "t1rt/composite.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/safety.hpp"

namespace t1rt {

namespace {
constexpr double kUsToS = 1e-6;
constexpr double kMsToS = 1e-3;

// Whether sim_status_t's three strings (scenario, clock, active_faults: int32 length with the NUL, bytes) each
// have a length of at least 1 that fits in the datagram. lcm-gen's decoder reads a length below 1 as
// length - 1 bytes, which overflows for INT32_MIN before its std::length_error: such a datagram is not decoded.
bool sim_status_strings_fit(const uint8_t* p, std::size_t size) {
  // fingerprint, utime, step (int64), real_time_factor (float): messages/t1/sim_status_t.lcm
  constexpr std::size_t kHead = 3 * sizeof(int64_t) + sizeof(float), kLength = sizeof(int32_t), kStrings = 3;
  std::size_t pos = kHead;
  for (std::size_t s = 0; s < kStrings; ++s) {
    if (size < pos + kLength) return false;
    const int32_t length = static_cast<int32_t>((uint32_t{p[pos]} << 24) | (uint32_t{p[pos + 1]} << 16) |
                                                (uint32_t{p[pos + 2]} << 8) | p[pos + 3]);
    pos += kLength;
    if (length < 1 || static_cast<std::size_t>(length) > size - pos) return false;
    pos += static_cast<std::size_t>(length);
  }
  return true;
}

CommandAuth::Stream stream_of(Supervisor::OperatorInput input) {
  return input == Supervisor::OperatorInput::kJoystick ? CommandAuth::kJoystickStream : CommandAuth::kCommandStream;
}
}  // namespace

const char* clock_name(ClockMode mode) { return mode == ClockMode::kLockstep ? "lockstep" : "realtime"; }

std::string resolve_lcm_url(const std::string& cli_url) {
  if (!cli_url.empty()) return cli_url;
  const char* env = std::getenv("T1_LCM_URL");
  if (env && *env) return env;
  return t1::kDefaultLcmUrl;
}

LcmTransport::~LcmTransport() {
  if (sock_ >= 0) close(sock_);
}

bool LcmTransport::open(const std::string& url, ClockMode clock, Supervisor* supervisor, CommandAuth* auth,
                        std::string* error, bool subscribe_sim_status, bool subscribe_robot_state,
                        CommandAuth* state_auth) {
  if (!sender_.open(url)) {
    *error = "cannot send on LCM URL '" + url +
             "' (a udpm://GROUP:PORT[?ttl=N] URL is needed; multicast "
             "route missing? run inside tools/netns)";
    return false;
  }
  sock_ = t1::open_lcm_group_socket(url);
  if (sock_ < 0) {
    *error = "cannot receive on LCM URL '" + url +
             "' (a udpm://GROUP:PORT URL is needed; multicast route "
             "missing? run inside tools/netns)";
    return false;
  }
  attach(clock, supervisor, auth, subscribe_sim_status, subscribe_robot_state, state_auth);
  return true;
}

void LcmTransport::attach(ClockMode clock, Supervisor* supervisor, CommandAuth* auth, bool subscribe_sim_status,
                          bool subscribe_robot_state, CommandAuth* state_auth) {
  clock_ = clock;
  supervisor_ = supervisor;
  auth_ = auth;
  state_auth_ = state_auth;
  buffer_.assign(kEncodeBufferBytes, 0);
  rx_.assign(t1::kLcmMaxDatagramBytes, 0);
  if (subscribe_robot_state) {
    subscribe(t1::CH_IMU, &LcmTransport::on_imu);
    subscribe(t1::CH_JOINT_STATE, &LcmTransport::on_joint);
  }
  // A signed message's tag decodes into this capacity (every buffer a decode or a swap can reach): no allocation.
  for (t1::joystick_t* m : {&joystick.msg, &joystick.scratch}) m->tag.reserve(kTagBytes);
  for (t1::imu_t* m : {&imu.msg, &imu.scratch}) m->tag.reserve(kTagBytes);
  for (t1::joint_state_t* m : {&joint.msg, &joint.scratch}) m->tag.reserve(kTagBytes);
  command_scratch_.tag.reserve(kTagBytes);
  for (t1::runtime_cmd_t& c : commands) c.tag.reserve(kTagBytes);
  subscribe(t1::CH_JOYSTICK, &LcmTransport::on_joystick);
  subscribe(t1::CH_RUNTIME_CMD, &LcmTransport::on_command);
  if (subscribe_sim_status) {
    // Decoding assigns the three strings; with this capacity (>= any accepted datagram) it never allocates.
    for (t1::sim_status_t* m : {&sim_status.msg, &sim_status.scratch})
      for (std::string* s : {&m->scenario, &m->clock, &m->active_faults}) s->reserve(kSimStatusMaxBytes);
    subscribe(t1::CH_SIM_STATUS, &LcmTransport::on_sim_status);
  }
}

void LcmTransport::subscribe(const char* channel, Handler handler) {
  subscriptions_.at(subscription_count_++) = {channel, handler};
}

int LcmTransport::deliver(const t1::LcmDatagram& m) {
  for (std::size_t i = 0; i < subscription_count_; ++i) {
    if (std::strcmp(m.channel, subscriptions_[i].channel) != 0) continue;
    if (m.fragment) ++decode_errors;
    else (this->*subscriptions_[i].handler)({m.payload, static_cast<uint32_t>(m.size)});
    return 1;
  }
  return 0;
}

int LcmTransport::handle_queued() {
  int handled = 0;
  t1::drain_lcm_group(sock_, rx_, [&](const t1::LcmDatagram& m) { handled += deliver(m); });
  return handled;
}

int LcmTransport::handle(int timeout_ms) {
  const int handled = handle_queued();
  if (handled > 0 || !t1::wait_readable(sock_, timeout_ms * kMsToS)) return handled;
  return handle_queued();
}

void LcmTransport::drain() { handle_queued(); }

double LcmTransport::stamp(int64_t utime) const {
  return clock_ == ClockMode::kLockstep ? static_cast<double>(utime) * kUsToS : monotonic_s();
}

// Safety rule R3 (src/safety_supervisor.cpp): decode into scratch; only a datagram that decodes exactly
// (no error, no trailing bytes) may replace the live message. String lengths below 1 never reach lcm-gen's
// decoder (sim_status_t's: sim_status_strings_fit; runtime_cmd_t's: CommandAuth::read_tag_size); the catch stays
// as a second line.
template <class Message>
bool LcmTransport::decode_scratch(MessageSlot<Message>& slot, const Datagram& d) {
  int used = -1;
  try {
    used = slot.scratch.decode(d.data, 0, static_cast<int>(d.size));
  } catch (const std::length_error&) {
  }
  if (used < 0 || static_cast<uint32_t>(used) != d.size) {
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

template <class Message>
bool LcmTransport::robot_frame(MessageSlot<Message>& slot, CommandAuth::Stream stream, const char* channel,
                               const Datagram& d) {
  int tag_size = 0;
  if (!CommandAuth::read_tag_size(stream, d.data, d.size, &tag_size)) {  // shorter than a frame: not decoded
    ++decode_errors;
    return false;
  }
  char what[64];
  if (!CommandAuth::tag_size_ok(tag_size)) {  // a tag vector of that size would allocate: never decoded
    if (state_auth_) {
      std::snprintf(what, sizeof(what), "%s frame", channel);
      state_auth_->refuse_tag_size(what, tag_size);
    }
    return false;
  }
  if (!decode_scratch(slot, d)) return false;
  const Message& m = slot.scratch;
  if (!state_auth_ || state_auth_->verify(stream, channel, d.data, d.size, m.sender_id, m.timestamp_us, m.tag_size))
    return true;
  std::snprintf(what, sizeof(what), "%s seq %lld", channel, static_cast<long long>(m.seq));
  state_auth_->refuse(what, m.sender_id);
  return false;
}

void LcmTransport::on_imu(const Datagram& d) {
  if (!robot_frame(imu, CommandAuth::kImuStream, t1::CH_IMU, d)) return;
  if (supervisor_ && !supervisor_->accept_imu_seq(imu.scratch.seq, monotonic_s())) return;
  commit(imu);
}

void LcmTransport::on_joint(const Datagram& d) {
  if (!robot_frame(joint, CommandAuth::kJointStream, t1::CH_JOINT_STATE, d)) return;
  if (supervisor_ && !supervisor_->accept_joint_seq(joint.scratch.seq, monotonic_s())) return;
  commit(joint);
  new_joint_state = true;
}

bool LcmTransport::decodable(Supervisor::OperatorInput input, const Datagram& d, const char* what) {
  int tag_size = 0;
  if (!CommandAuth::read_tag_size(stream_of(input), d.data, d.size, &tag_size)) {
    ++decode_errors;
    return false;
  }
  if (CommandAuth::tag_size_ok(tag_size)) return true;
  if (auth_) auth_->refuse_tag_size(what, tag_size);
  return false;
}

template <class Message>
bool LcmTransport::admitted(Supervisor::OperatorInput input, const char* channel, const Datagram& d, const Message& m,
                            const char* what) {
  const bool authorised =
      auth_ && auth_->verify(stream_of(input), channel, d.data, d.size, m.sender_id, m.timestamp_us, m.tag_size);
  if (Supervisor::admits(input, authorised)) return true;  // safety rule R11
  if (auth_) auth_->refuse(what, m.sender_id);
  return false;
}

void LcmTransport::on_joystick(const Datagram& d) {
  if (!decodable(Supervisor::OperatorInput::kJoystick, d, "joystick_t") || !decode_scratch(joystick, d)) return;
  if (admitted(Supervisor::OperatorInput::kJoystick, t1::CH_JOYSTICK, d, joystick.scratch, "joystick_t"))
    commit(joystick);
}

void LcmTransport::on_sim_status(const Datagram& d) {
  if (d.size > kSimStatusMaxBytes) {
    ++sim_status_oversized;
    return;
  }
  if (!sim_status_strings_fit(d.data, d.size)) {
    ++decode_errors;
    return;
  }
  if (decode_scratch(sim_status, d)) commit(sim_status);
}

void LcmTransport::on_command(const Datagram& d) {
  if (!decodable(Supervisor::OperatorInput::kCommand, d, "runtime_cmd_t")) return;
  t1::runtime_cmd_t& c = command_scratch_;
  const int used = c.decode(d.data, 0, static_cast<int>(d.size));
  if (used < 0 || static_cast<uint32_t>(used) != d.size) {
    ++decode_errors;
    return;
  }
  const bool estop = c.verb == "estop";
  char what[128];
  std::snprintf(what, sizeof(what), "runtime_cmd_t '%.24s %.64s'", c.verb.c_str(), c.argument.c_str());
  if (!admitted(estop ? Supervisor::OperatorInput::kEstop : Supervisor::OperatorInput::kCommand, t1::CH_RUNTIME_CMD, d,
                c, what))
    return;
  if (estop) {  // safety rule R2: outside the bounded queue
    estop_pending = true;
    return;
  }
  if (command_count >= kCommandQueue) {
    ++commands_dropped;
    return;
  }
  std::swap(commands[command_count++], c);
}

}  // namespace t1rt
