// t1rt_bench_lcm_peer: plays a lockstep simulator and measures state->command latency over LCM. For each
// k it publishes T1_IMU then T1_JOINT_STATE (seq k, utime k * 2 ms of sim time) and waits for the
// T1_JOINT_CMD whose state_seq is k; latency = publish of the state -> arrival of its command (CLOCK_MONOTONIC).
// The answering side (the target) is t1-runtime --clock lockstep or t1rt_bench_lcm_echo; with --echo-url a
// t1rt_bench_lcm_echo on a second LCM URL is driven in alternation, so both see the same machine load. Ticks on which the
// runtime evaluated the policy are told apart by the T1_ACTION it publishes after that tick's command (its utime is
// the state's); the peer reads what is queued before each exchange, so such telemetry is never timed.
// --joystick-every N sends a T1_JOYSTICK right after every Nth state, inside its timed exchange (the runtime
// decodes, and with --key verifies, it before that tick), signed with --key FILE's first sender if given; the
// same to the --echo-url side (signed with --echo-key FILE), which may be a second t1-runtime: then the two
// runtimes are compared exchange by exchange under the same load (--wait-policy waits for both).
// Prints one JSON line for tests/bench/runtime_bench.py.
#include <lcm/lcm.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "t1/action_t.hpp"
#include "t1/controller_status_t.hpp"
#include "t1/imu_t.hpp"
#include "t1/joint_command_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1/joystick_t.hpp"
#include "t1_contract.hpp"
#include "t1rt/command_auth.hpp"
#include "t1rt/constants.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/transport.hpp"

namespace {
using t1rt::bench::Args;
using t1rt::bench::usage_error;

constexpr int64_t kSimTickUs = 2000;        // lockstep sim time per state [us] (500 Hz)
constexpr float kGravityMps2 = 9.81f;       // accelerometer reading at rest [m/s^2]
constexpr int kConnectRetryMs = 100;        // re-send state 0 until the answering process listens
constexpr int kLastTelemetryMs = 100;       // wait for the telemetry that follows the last command
constexpr int kMaxWarmupExchanges = 20000;  // 40 s of sim time: more means the runtime never got to POLICY
// The encoders move one count per state: still ones under PD torque are a frozen encoder to the runtime
// (rule R9 of runtime/src/safety_supervisor.cpp), which would latch FAULT before POLICY.
constexpr float kEncoderDitherRad = 1e-4f;

const char* kHelp =
    "usage: t1rt_bench_lcm_peer [--count N] [--warmup N] [--wait-policy] [--timeout-ms MS] [--connect-s S]\n"
    "                           [--lcm-url URL] [--echo-url URL] [--joystick-every N [--key F] [--echo-key F]]\n"
    "  --lcm-url URL    the target's LCM URL (default $T1_LCM_URL, else the contract default)\n"
    "  --echo-url URL   also drive a t1rt_bench_lcm_echo listening on URL, alternating exchange by exchange\n"
    "  --count N        recorded exchanges (default 5000)\n"
    "  --warmup N       unrecorded exchanges first (default 2000)\n"
    "  --wait-policy    keep warming up until T1_CONTROLLER_STATUS reports POLICY (for t1-runtime --autostart)\n"
    "  --timeout-ms MS  give up when one command takes longer (default 1000)\n"
    "  --connect-s S    how long to wait for the first answer (default 10)\n"
    "  --joystick-every N  a T1_JOYSTICK after every Nth state, in its timed exchange (default 0: none)\n"
    "  --key FILE       sign that joystick with FILE's first sender (messages/auth.py)\n"
    "  --echo-key FILE  the same for the --echo-url side's joystick\n"
    "prints one JSON line: latency [us] median/p99/max, overall, split into policy ticks, joystick ticks (no\n"
    "policy) and the others, echo\n";

struct Peer {
  lcm_t* lcm = nullptr;
  t1::imu_t imu{};
  t1::joint_state_t state{};
  t1::joint_command_t command{};
  t1::controller_status_t status{};
  t1::action_t action{};
  t1::joystick_t joystick{};
  int joystick_every = 0;
  std::shared_ptr<const t1rt::KeyRing> key;  // null: the joystick goes unsigned
  int64_t last_timestamp_us = 0;
  std::vector<uint8_t> joystick_bytes;
  std::vector<uint8_t> buffer;
  std::vector<int64_t> policy_seqs;  // states answered by a policy tick (from T1_ACTION's utime)
  int64_t want_seq = -1;
  int64_t answer_ns = 0;  // arrival time of the command answering want_seq
  bool answered = false;
  int8_t mode = -1;  // latest controller_status_t.mode, -1 before the first status
  std::string fault;

  template <class M>
  void publish(const char* channel, const M& m) {
    const int size = m.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    if (size > 0) lcm_publish(lcm, channel, buffer.data(), static_cast<unsigned>(size));
  }
};

void on_command(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  const int64_t now = t1rt::monotonic_ns();
  auto* p = static_cast<Peer*>(user);
  if (p->command.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
  if (p->command.state_seq == p->want_seq && !p->answered) {
    p->answered = true;
    p->answer_ns = now;
  }
}
void on_action(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  auto* p = static_cast<Peer*>(user);
  if (p->action.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
  p->policy_seqs.push_back(std::llround(static_cast<double>(p->action.utime) / kSimTickUs));
}
void on_status(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  auto* p = static_cast<Peer*>(user);
  if (p->status.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
  p->mode = p->status.mode;
  p->fault = p->status.last_fault;
}

// State k's joystick_t encoded into p.joystick_bytes, signed (sender, fresh increasing timestamp, tag) when the
// peer has a key: made before the exchange is timed, so only its sending is the peer's share of it.
void prepare_joystick(Peer& p, int64_t k) {
  p.joystick.utime = k * kSimTickUs;
  p.joystick.seq = k;
  if (p.key) {
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    p.last_timestamp_us =
        std::max(p.last_timestamp_us + 1, static_cast<int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000);
    p.joystick.sender_id = p.key->sender_id(0);
    p.joystick.timestamp_us = p.last_timestamp_us;
    p.joystick_bytes = p.key->encode_signed(0, t1::CH_JOYSTICK, p.joystick);
  } else {
    p.joystick_bytes.resize(static_cast<std::size_t>(p.joystick.getEncodedSize()));
    p.joystick.encode(p.joystick_bytes.data(), 0, static_cast<int>(p.joystick_bytes.size()));
  }
}

// Publishes state k; returns the latency [us] of its answer, or a negative value on timeout.
double exchange(Peer& p, int64_t k, int timeout_ms) {
  p.imu.seq = p.state.seq = k;
  p.imu.utime = p.state.utime = k * kSimTickUs;
  while (lcm_handle_timeout(p.lcm, 0) > 0) {  // the previous answer's telemetry: read, untimed
  }
  p.want_seq = k;
  for (float& q : p.state.q) q = static_cast<float>(k % 2) * kEncoderDitherRad;
  p.answered = false;
  const bool stick = p.joystick_every > 0 && k % p.joystick_every == 0;
  if (stick) prepare_joystick(p, k);
  p.publish(t1::CH_IMU, p.imu);
  const int64_t t0 = t1rt::monotonic_ns();
  p.publish(t1::CH_JOINT_STATE, p.state);
  if (stick)
    lcm_publish(p.lcm, t1::CH_JOYSTICK, p.joystick_bytes.data(), static_cast<unsigned>(p.joystick_bytes.size()));
  const int64_t deadline = t0 + static_cast<int64_t>(timeout_ms) * 1'000'000;
  while (!p.answered) {
    const int64_t left_ms = (deadline - t1rt::monotonic_ns()) / 1'000'000;
    if (left_ms <= 0 || lcm_handle_timeout(p.lcm, static_cast<int>(left_ms)) < 0) return -1.0;
  }
  return static_cast<double>(p.answer_ns - t0) * 1e-3;
}

// Opens LCM on `url` and subscribes to what the answering side sends; false if LCM cannot start.
bool open_peer(Peer& p, const std::string& url) {
  p.lcm = lcm_create(url.c_str());
  if (!p.lcm) return false;
  p.buffer.resize(static_cast<std::size_t>(std::max(p.state.getEncodedSize(), p.imu.getEncodedSize())));
  p.imu.quat[0] = 1.0f;  // upright, at rest: (w x y z) = identity
  p.imu.accel[2] = kGravityMps2;
  lcm_subscribe(p.lcm, t1::CH_JOINT_CMD, &on_command, &p);
  lcm_subscribe(p.lcm, t1::CH_ACTION, &on_action, &p);
  lcm_subscribe(p.lcm, t1::CH_CONTROLLER_STATUS, &on_status, &p);
  return true;
}

// The answering process may still be starting: re-send state 0 until it answers.
bool connect(Peer& p, double connect_s) {
  const int tries = static_cast<int>(connect_s * 1000.0 / kConnectRetryMs) + 1;
  for (int i = 0; i < tries; ++i)
    if (exchange(p, 0, kConnectRetryMs) >= 0.0) return true;
  return false;
}
}  // namespace

int main(int argc, char** argv) {
  int count = 5000, warmup = 2000, timeout_ms = 1000;
  double connect_s = 10.0;
  bool wait_policy = false;
  std::string url, echo_url, key_path, echo_key_path;
  int joystick_every = 0;
  Args args(argc, argv);
  while (args.next()) {
    const std::string f = args.flag();
    if (f == "--help" || f == "-h") {
      std::fputs(kHelp, stdout);
      return 0;
    } else if (f == "--count") count = static_cast<int>(args.number(1));
    else if (f == "--warmup") warmup = static_cast<int>(args.number(0));
    else if (f == "--wait-policy") wait_policy = true;
    else if (f == "--timeout-ms") timeout_ms = static_cast<int>(args.number(1));
    else if (f == "--connect-s") connect_s = args.number(0.1);
    else if (f == "--lcm-url") url = args.value();
    else if (f == "--echo-url") echo_url = args.value();
    else if (f == "--joystick-every") joystick_every = static_cast<int>(args.number(1));
    else if (f == "--key") key_path = args.value();
    else if (f == "--echo-key") echo_key_path = args.value();
    else usage_error(argv[0], "unknown argument '" + f + "'");
  }
  const bool with_echo = !echo_url.empty();
  Peer p, echo;
  for (auto [peer, path] : {std::pair<Peer*, std::string*>{&p, &key_path}, {&echo, &echo_key_path}}) {
    peer->joystick_every = joystick_every;
    std::string error;
    if (!path->empty() && !(peer->key = t1rt::KeyRing::load(*path, &error))) usage_error(argv[0], error);
  }
  if (!open_peer(p, t1rt::resolve_lcm_url(url)) || (with_echo && !open_peer(echo, echo_url))) {
    std::fprintf(stderr, "%s: lcm_create failed\n", argv[0]);
    return t1rt::bench::kExitRun;
  }
  if (!connect(p, connect_s) || (with_echo && !connect(echo, connect_s))) {
    std::fprintf(stderr, "%s: no T1_JOINT_CMD answered state 0 within %.1f s%s\n", argv[0], connect_s,
                 with_echo ? " (target or echo)" : "");
    return t1rt::bench::kExitRun;
  }
  // One step: the target, then (interleaved, so both see the same machine load) the echo.
  auto step = [&](int64_t k, double* target_us, double* echo_us) {
    *target_us = exchange(p, k, timeout_ms);
    *echo_us = with_echo ? exchange(echo, k, timeout_ms) : 0.0;
    if (*target_us >= 0.0 && *echo_us >= 0.0) return true;
    std::fprintf(stderr, "%s: state %lld unanswered by the %s after %d ms\n", argv[0], static_cast<long long>(k),
                 *target_us < 0.0 ? "target" : "echo", timeout_ms);
    return false;
  };
  int64_t k = 1;
  int warm = 0;
  double target_us = 0.0, echo_us = 0.0;
  // An echo sends no status (mode -1); a second runtime must reach POLICY too.
  auto in_policy = [](const Peer& x) { return x.mode == t1::joint_command_t::MODE_POLICY; };
  for (; warm < warmup || (wait_policy && (!in_policy(p) || (echo.mode != -1 && !in_policy(echo)))); ++k, ++warm) {
    if (warm >= kMaxWarmupExchanges || p.mode == t1::joint_command_t::MODE_FAULT) {
      std::fprintf(stderr, "%s: answering process did not reach POLICY (status mode %d, last fault '%s')\n", argv[0],
                   p.mode, p.fault.c_str());
      return t1rt::bench::kExitRun;
    }
    if (!step(k, &target_us, &echo_us)) return t1rt::bench::kExitRun;
  }

  std::vector<double> all_us, echo_all_us;
  std::vector<int64_t> seqs;
  all_us.reserve(static_cast<std::size_t>(count));
  seqs.reserve(static_cast<std::size_t>(count));
  echo_all_us.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i, ++k) {
    if (!step(k, &target_us, &echo_us)) return t1rt::bench::kExitRun;
    all_us.push_back(target_us);
    seqs.push_back(k);
    if (with_echo) echo_all_us.push_back(echo_us);
  }
  lcm_handle_timeout(p.lcm, kLastTelemetryMs);  // the last answer's telemetry and a last status
  while (lcm_handle_timeout(p.lcm, 0) > 0) {
  }
  std::sort(p.policy_seqs.begin(), p.policy_seqs.end());
  // Policy ticks; ticks with a joystick (and no policy); plain ticks (neither): the same run's reference.
  std::vector<double> policy_us, joystick_us, plain_us;
  for (std::size_t i = 0; i < all_us.size(); ++i) {
    const bool policy = std::binary_search(p.policy_seqs.begin(), p.policy_seqs.end(), seqs[i]);
    const bool stick = joystick_every > 0 && seqs[i] % joystick_every == 0;
    (policy ? policy_us : stick ? joystick_us : plain_us).push_back(all_us[i]);
  }
  std::string out;
  t1rt::bench::json_summary(out, "latency_us", t1rt::bench::summarize(all_us));
  t1rt::bench::json_summary(out, "policy_tick_us", t1rt::bench::summarize(policy_us));
  t1rt::bench::json_summary(out, "joystick_tick_us", t1rt::bench::summarize(joystick_us));
  t1rt::bench::json_summary(out, "plain_tick_us", t1rt::bench::summarize(plain_us));
  t1rt::bench::json_summary(out, "echo_us", t1rt::bench::summarize(echo_all_us));
  t1rt::bench::json_number(out, "warmup_exchanges", warm);
  t1rt::bench::json_number(out, "final_mode", p.mode);
  t1rt::bench::json_print(out);
  lcm_destroy(p.lcm);
  if (with_echo) lcm_destroy(echo.lcm);
  return 0;
}
