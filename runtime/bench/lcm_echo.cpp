// t1rt_bench_lcm_echo: the raw-LCM reference for the state->command latency bench. Answers every
// T1_JOINT_STATE with a T1_JOINT_CMD of the same type and size the runtime sends (state_seq = the state's
// seq), doing nothing else: decode, fill, encode, publish. What t1-runtime adds on top is its tick.
#include <lcm/lcm.h>

#include <csignal>
#include <cstdint>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "t1/joint_command_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1_contract.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/transport.hpp"

namespace {
using t1rt::bench::Args;
using t1rt::bench::usage_error;

constexpr int kHandleSliceMs = 100;  // how often the loop re-checks the duration and SIGTERM

volatile std::sig_atomic_t g_stop = 0;
void on_stop(int) { g_stop = 1; }

struct Echo {
  lcm_t* lcm = nullptr;
  t1::joint_state_t state{};
  t1::joint_command_t command{};
  std::vector<uint8_t> buffer;
  int64_t answered = 0;
};

void on_state(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  auto* echo = static_cast<Echo*>(user);
  if (echo->state.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
  echo->command.utime = echo->state.utime;
  echo->command.seq = echo->answered++;
  echo->command.state_seq = echo->state.seq;
  const int size = echo->command.encode(echo->buffer.data(), 0, static_cast<int>(echo->buffer.size()));
  if (size > 0) lcm_publish(echo->lcm, t1::CH_JOINT_CMD, echo->buffer.data(), static_cast<unsigned>(size));
}

const char* kHelp =
    "usage: t1rt_bench_lcm_echo [--seconds S] [--lcm-url URL]\n"
    "  answers each T1_JOINT_STATE with a same-sized T1_JOINT_CMD (state_seq = seq) until S seconds or SIGTERM\n";
}  // namespace

int main(int argc, char** argv) {
  double seconds = 60.0;
  std::string url;
  Args args(argc, argv);
  while (args.next()) {
    const std::string f = args.flag();
    if (f == "--help" || f == "-h") {
      std::fputs(kHelp, stdout);
      return 0;
    } else if (f == "--seconds") seconds = args.number(0.01);
    else if (f == "--lcm-url") url = args.value();
    else usage_error(argv[0], "unknown argument '" + f + "'");
  }
  Echo echo;
  echo.buffer.resize(static_cast<std::size_t>(echo.command.getEncodedSize()));
  echo.lcm = lcm_create(t1rt::resolve_lcm_url(url).c_str());
  if (!echo.lcm) {
    std::fprintf(stderr, "%s: lcm_create failed for %s\n", argv[0], t1rt::resolve_lcm_url(url).c_str());
    return t1rt::bench::kExitRun;
  }
  lcm_subscribe(echo.lcm, t1::CH_JOINT_STATE, &on_state, &echo);
  std::signal(SIGTERM, on_stop);
  std::signal(SIGINT, on_stop);
  const int64_t end_ns = t1rt::monotonic_ns() + static_cast<int64_t>(seconds * 1e9);
  while (!g_stop && t1rt::monotonic_ns() < end_ns) {
    if (lcm_handle_timeout(echo.lcm, kHandleSliceMs) < 0) break;
  }
  std::fprintf(stderr, "%s: answered %lld states\n", argv[0], static_cast<long long>(echo.answered));
  lcm_destroy(echo.lcm);
  return 0;
}
