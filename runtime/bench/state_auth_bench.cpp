// The cost of verifying the robot's state (--robot-key): two lockstep runtimes in this process, one taking
// unsigned state (verification off), one taking only signed state (on), ticked in alternating blocks so both
// see the same machine; each tick = receive the imu_t + joint_state_t (and verify them) + the control tick.
// Prints one JSON line: median / p99 of policy ticks [us] for both, and on / off. Needs LCM (tools/netns).
//   t1rt_bench_state_auth --policy P [--lcm-url URL] [--blocks N] [--block-ticks N]
#include <fcntl.h>
#include <lcm/lcm.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "t1_contract.hpp"
#include "t1rt/controller.hpp"

namespace {
constexpr int kKeyFill = 0x5a;           // the bench's robot key: 32 bytes of this value (not a secret)
constexpr int kPortOffsets[2] = {7, 8};  // the two runtimes' LCM ports: the URL's + these

int64_t wall_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

std::string on_port(const std::string& url, int offset) {
  const auto colon = url.rfind(':'), end = url.find('?', colon);
  const int port = std::stoi(url.substr(colon + 1, end - colon - 1)) + offset;
  return url.substr(0, colon + 1) + std::to_string(port) + (end == std::string::npos ? "" : url.substr(end));
}

std::shared_ptr<const t1rt::KeyRing> bench_ring() {
  const std::string path = "/tmp/t1rt_bench_robot_" + std::to_string(getpid()) + ".key";
  const int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  std::string line = "1 ";
  char hex[3];
  for (std::size_t i = 0; i < t1rt::kKeyBytes; ++i) std::snprintf(hex, sizeof(hex), "%02x", kKeyFill), line += hex;
  line += "\n";
  const bool written = fd >= 0 && write(fd, line.data(), line.size()) == static_cast<ssize_t>(line.size());
  if (fd >= 0) close(fd);
  std::string error;
  auto ring = written ? t1rt::KeyRing::load(path, &error) : nullptr;
  unlink(path.c_str());
  return ring;
}

struct Side {
  std::unique_ptr<t1rt::Controller> ctrl;
  lcm_t* lcm = nullptr;
  std::shared_ptr<const t1rt::KeyRing> ring;  // null: unsigned state (verification off)
  t1::imu_t imu{};
  t1::joint_state_t js{};
  int64_t k = 0, last_us = 0;
  std::vector<double> policy_us;

  template <class M>
  void send(const char* channel, M m) {
    std::vector<uint8_t> buf;
    if (ring) {
      m.sender_id = 1;
      m.timestamp_us = last_us = std::max(last_us + 1, wall_us());
      buf = ring->encode_signed(0, channel, m);
    } else {
      buf.resize(static_cast<std::size_t>(m.getEncodedSize()));
      m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    }
    lcm_publish(lcm, channel, buf.data(), static_cast<unsigned>(buf.size()));
  }
  bool tick(bool record) {
    ++k;
    imu.utime = js.utime = k * 2000;
    imu.seq = js.seq = k;
    send(t1::CH_IMU, imu);
    send(t1::CH_JOINT_STATE, js);
    const int64_t before = ctrl->policy_ticks();
    const auto t0 = std::chrono::steady_clock::now();
    const bool ok = ctrl->step_lockstep(500);
    const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
    if (record && ctrl->policy_ticks() > before) policy_us.push_back(us);
    while (lcm_handle_timeout(lcm, 0) > 0) {
    }
    return ok;
  }
};
}  // namespace

int main(int argc, char** argv) {
  std::string policy, url = t1rt::resolve_lcm_url("");
  int blocks = 20, block_ticks = 500;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) t1rt::bench::usage_error(argv[0], a + " needs a value");
      return argv[++i];
    };
    if (a == "--policy") policy = value();
    else if (a == "--lcm-url") url = value();
    else if (a == "--blocks") blocks = std::stoi(value());
    else if (a == "--block-ticks") block_ticks = std::stoi(value());
    else t1rt::bench::usage_error(argv[0], "unknown argument " + a);
  }
  if (policy.empty()) t1rt::bench::usage_error(argv[0], "--policy PATH is required");
  Side sides[2];
  for (int s = 0; s < 2; ++s) {
    t1rt::ControllerOptions opt;
    opt.policy_path = policy;
    opt.lcm_url = on_port(url, kPortOffsets[s]);
    opt.clock = t1rt::ClockMode::kLockstep;
    opt.quiet = opt.autostart = true;
    opt.safety.prepare_duration_s = 0.02;
    opt.auth = t1rt::AuthMode::kUnauthenticated;
    sides[s].ring = s == 1 ? bench_ring() : nullptr;
    opt.robot_keys = sides[s].ring;
    if (s == 1 && !sides[s].ring) {
      std::fprintf(stderr, "cannot write the bench's robot key\n");
      return t1rt::bench::kExitRun;
    }
    sides[s].ctrl =
        std::make_unique<t1rt::Controller>(opt, std::make_unique<t1rt::PolicyEngine>(t1rt::load_artifact(policy)));
    std::string error;
    sides[s].lcm = lcm_create(opt.lcm_url.c_str());
    if (!sides[s].lcm || !sides[s].ctrl->open(&error)) {
      std::fprintf(stderr, "cannot open LCM %s: %s (run inside tools/netns)\n", opt.lcm_url.c_str(), error.c_str());
      return t1rt::bench::kExitRun;
    }
    const t1rt::JointArray pose = sides[s].ctrl->policy().artifact().default_pose;
    std::copy(pose.begin(), pose.end(), sides[s].js.q);
    sides[s].imu.quat[0] = 1.0f;
    for (int k = 0; k < block_ticks; ++k) sides[s].tick(false);  // warm-up into POLICY
  }
  for (int b = 0; b < blocks; ++b)
    for (Side& side : sides)
      for (int k = 0; k < block_ticks; ++k)
        if (!side.tick(true)) {
          std::fprintf(stderr, "a tick timed out\n");
          return t1rt::bench::kExitRun;
        }
  for (Side& side : sides) {
    if (side.ctrl->supervisor().mode() != t1rt::Mode::kPolicy || side.ctrl->state_auth().refused_total() != 0) {
      std::fprintf(stderr, "not in POLICY on its own state: %s %s\n", side.ctrl->supervisor().last_fault(),
                   side.ctrl->state_auth().last_refusal());
      return t1rt::bench::kExitRun;
    }
  }
  const auto off = t1rt::bench::summarize(sides[0].policy_us), on = t1rt::bench::summarize(sides[1].policy_us);
  std::string out;
  t1rt::bench::json_summary(out, "off_policy_tick_us", off);
  t1rt::bench::json_summary(out, "on_policy_tick_us", on);
  t1rt::bench::json_number(out, "ratio_median", on.median / off.median);
  t1rt::bench::json_number(out, "ratio_p99", on.p99 / off.p99);
  t1rt::bench::json_number(out, "policy_ticks", static_cast<double>(sides[0].policy_us.size()));
  t1rt::bench::json_print(out);
  for (Side& side : sides) lcm_destroy(side.lcm);
  return 0;
}
