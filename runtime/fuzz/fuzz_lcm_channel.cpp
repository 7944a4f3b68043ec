// libFuzzer harness: one inbound LCM channel of t1-runtime, from the datagram to what the loop sees.
// Built once per channel (T1_FUZZ_CHANNEL: imu, joint_state, joystick, runtime_cmd, sim_status).
// Input: byte 0 = flags, the rest = the message payload (or, with kRawDatagram, the whole UDP datagram).
//   kSign:            patch sender_id / timestamp_us / tag_size to the harness key's and sign the payload,
//                     so the fuzzer also reaches what follows an accepted signature;
//   kUnauthenticated: the bench mode (every message taken) instead of --key / --robot-key;
//   kLockstep:        lockstep clock (stamps from utime);
//   kRawDatagram:     the bytes are the datagram itself (LCM header and channel name fuzzed too).
// Path: t1::parse_lcm_datagram -> LcmTransport::deliver (read_tag_size, decode, CommandAuth::verify, rules
// R3/R11/R12) -> the slots and queue -> the loop's use: handle_commands' verbs, gate_joystick, a supervisor
// tick and a policy step on the state. The datagram is delivered twice (the second: a replay).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "fuzz_support.hpp"
#include "t1_contract.hpp"
#include "t1_lcm_group.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/transport.hpp"

namespace {
enum Flags : uint8_t { kSign = 1, kUnauthenticated = 2, kLockstep = 4, kRawDatagram = 8 };
constexpr std::size_t kSignedTail = 8 + 8 + 2 + t1rt::kTagBytes;  // sender_id, timestamp_us, tag_size, tag

#define T1_FUZZ_STR2(x) #x
#define T1_FUZZ_STR(x) T1_FUZZ_STR2(x)
const char* channel_of(const char* which) {
  if (!std::strcmp(which, "imu")) return t1::CH_IMU;
  if (!std::strcmp(which, "joint_state")) return t1::CH_JOINT_STATE;
  if (!std::strcmp(which, "joystick")) return t1::CH_JOYSTICK;
  if (!std::strcmp(which, "runtime_cmd")) return t1::CH_RUNTIME_CMD;
  return t1::CH_SIM_STATUS;
}
const char* const kChannel = channel_of(T1_FUZZ_STR(T1_FUZZ_CHANNEL));
const bool kSignedChannel = std::strcmp(kChannel, t1::CH_SIM_STATUS) != 0;

void put_be64(uint8_t* p, int64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<uint8_t>(static_cast<uint64_t>(v) >> (56 - 8 * i));
}

// The payload signed as the harness's sender, now (messages/auth.py's layout: the tail of every signed type).
void sign(std::vector<uint8_t>& payload) {
  if (payload.size() < 8 + kSignedTail) return;
  uint8_t* tail = payload.data() + payload.size() - kSignedTail;
  put_be64(tail, t1rt::fuzz::kSenderId);
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  put_be64(tail + 8, static_cast<int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000);
  tail[16] = 0;
  tail[17] = static_cast<uint8_t>(t1rt::kTagBytes);
  t1rt::fuzz::key_ring()->sign(0, kChannel, payload.data(), payload.size());
}

std::vector<uint8_t> datagram_of(const std::vector<uint8_t>& payload) {
  std::vector<uint8_t> d = {0x4C, 0x43, 0x30, 0x32, 0, 0, 0, 1};  // "LC02", sequence number 1
  d.insert(d.end(), kChannel, kChannel + std::strlen(kChannel) + 1);
  d.insert(d.end(), payload.begin(), payload.end());
  return d;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace t1rt;
  if (size < 1) return 0;
  const uint8_t flags = data[0];
  std::vector<uint8_t> bytes(data + 1, data + size);
  if (!(flags & kRawDatagram)) {
    if ((flags & kSign) && kSignedChannel) sign(bytes);
    bytes = datagram_of(bytes);
  }

  Supervisor supervisor;
  supervisor.set_autostart(true);
  CommandAuth auth, state_auth;
  const AuthMode mode = (flags & kUnauthenticated) ? AuthMode::kUnauthenticated : AuthMode::kSigned;
  std::string error;
  if (!auth.open(mode, fuzz::key_ring(), AuthConfig{}, &error) ||
      !state_auth.open(mode, fuzz::key_ring(), AuthConfig{}, &error))
    std::abort();
  LcmTransport transport;
  const ClockMode clock = (flags & kLockstep) ? ClockMode::kLockstep : ClockMode::kRealtime;
  const bool composite = !kSignedChannel;
  transport.attach(clock, &supervisor, &auth, composite, true, &state_auth);

  for (int copy = 0; copy < 2; ++copy) {
    t1::LcmDatagram m;
    if (t1::parse_lcm_datagram(bytes.data(), bytes.size(), &m) && m.channel != nullptr) transport.deliver(m);
  }

  // A state channel's partner slot holds a healthy frame of the same time, so the loop ticks on the fuzzed one.
  if (transport.imu.have && !transport.joint.have) {
    transport.joint.have = true;  // zero positions and velocities, no status bits
    transport.joint.stamp_s = transport.imu.stamp_s;
  } else if (transport.joint.have && !transport.imu.have) {
    transport.imu.have = true;  // upright, at rest
    transport.imu.msg.quat[0] = 1.0f;
    transport.imu.stamp_s = transport.joint.stamp_s;
  }

  // The loop's side (Controller::handle_commands and tick): verbs, joystick gate, a supervisor tick, a policy step.
  static PolicyEngine engine(fuzz::small_artifact());
  engine.reset();
  for (std::size_t i = 0; i < transport.command_count; ++i) {
    const t1::runtime_cmd_t& c = transport.commands[i];
    Mode target;
    if (c.verb == "reset") supervisor.reset();
    else if (c.verb == "set_mode" && parse_mode(c.argument.c_str(), &target)) supervisor.request_mode(target);
  }
  if (transport.estop_pending) supervisor.estop();
  const double now_s = clock == ClockMode::kLockstep ? transport.joint.stamp_s : monotonic_s();
  float command[3] = {0, 0, 0};
  const auto& js = transport.joystick;
  supervisor.gate_joystick(now_s, js.have, js.stamp_s, &js.msg.vx, engine.artifact().command_ranges, command);
  fuzz::loop_tick(supervisor, engine, transport.state_view(now_s, composite), command);
  return 0;
}
