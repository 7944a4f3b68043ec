// t1-lcm-logger: the project's LCM logger (sim_hil/lcmlog/capture.py runs it), writing LCM's event-log format.
// Why not lcm-logger: it takes messages through an LCM subscription, whose queue holds 30 messages; a lockstep
// run at 10× real time sends ~20 000 a second, so a logger starved for a couple of milliseconds on a loaded
// machine lost bursts of them. This one reads the group from its own socket (messages/cpp/t1_lcm_group.hpp)
// with a large kernel receive buffer, the only queue, and writes every datagram of the named channels as it
// reads it (buffered; flushed every --flush-interval ms so a reader sees it, and at SIGINT / SIGTERM).
//
//   t1-lcm-logger --lcm-url URL --channels CH1,CH2,... [--flush-interval MS] FILE
#include <lcm/eventlog.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <t1_lcm_group.hpp>

namespace {
constexpr int kObserverReceiveBufferBytes = 1 << 22;  // the kernel doubles it, capped by net.core.rmem_max
constexpr double kWaitSliceS = 0.005;                 // how often the loop looks at the stop flag and flush
constexpr int kExitUsage = 2, kExitRuntime = 1;
volatile std::sig_atomic_t g_stop = 0;

void on_signal(int) { g_stop = 1; }

int64_t wall_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

int usage(const char* why) {
  std::fprintf(stderr,
               "t1-lcm-logger: %s\nusage: t1-lcm-logger --lcm-url URL --channels CH1,CH2,... "
               "[--flush-interval MS] FILE\n",
               why);
  return kExitUsage;
}
}  // namespace

int main(int argc, char** argv) {
  std::string url, path;
  std::set<std::string> channels;
  long flush_ms = 100;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i], value;
    const auto eq = a.find('=');
    const bool inline_value = a.rfind("--", 0) == 0 && eq != std::string::npos;
    if (inline_value) {  // --name=value as well as --name value
      value = a.substr(eq + 1);
      a = a.substr(0, eq);
    }
    const bool option = a == "--lcm-url" || a == "--channels" || a == "--flush-interval";
    if (option && !inline_value) {
      if (i + 1 >= argc) return usage((a + " needs a value").c_str());
      value = argv[++i];
    }
    if (a == "--lcm-url") url = value;
    else if (a == "--channels") {
      std::stringstream list(value);
      for (std::string c; std::getline(list, c, ',');)
        if (!c.empty()) channels.insert(c);
    } else if (a == "--flush-interval") {
      char* end = nullptr;
      flush_ms = std::strtol(value.c_str(), &end, 10);
      if (value.empty() || *end != '\0' || flush_ms <= 0)
        return usage(("--flush-interval " + value + ": a whole number of ms > 0").c_str());
    } else if (!a.empty() && a[0] != '-' && path.empty()) path = a;
    else return usage(("unexpected argument '" + std::string(argv[i]) + "'").c_str());
  }
  if (url.empty() || channels.empty() || path.empty()) return usage("--lcm-url, --channels and FILE are required");

  const int sock = t1::open_lcm_group_socket(url, kObserverReceiveBufferBytes);
  if (sock < 0) {
    std::fprintf(stderr, "t1-lcm-logger: cannot receive on '%s' (a udpm://GROUP:PORT URL; inside tools/netns)\n",
                 url.c_str());
    return kExitRuntime;
  }
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "w");
  if (log == nullptr) {
    std::fprintf(stderr, "t1-lcm-logger: cannot write '%s': %s\n", path.c_str(), std::strerror(errno));
    close(sock);
    return kExitRuntime;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  std::vector<uint8_t> rx(t1::kLcmMaxDatagramBytes);
  int64_t logged = 0, fragments = 0, write_errors = 0;
  auto last_flush = std::chrono::steady_clock::now();
  for (;;) {
    const bool stopping = g_stop;  // then one last pass over what is queued
    if (!stopping) t1::wait_readable(sock, kWaitSliceS);
    t1::drain_lcm_group(sock, rx, [&](const t1::LcmDatagram& m) {
      if (channels.count(m.channel) == 0) return;
      if (m.fragment) {  // never one of the project's channels; counted, not reassembled
        ++fragments;
        return;
      }
      lcm_eventlog_event_t event{};
      event.timestamp = wall_us();
      event.channellen = static_cast<int32_t>(std::strlen(m.channel));
      event.datalen = static_cast<int32_t>(m.size);
      event.channel = const_cast<char*>(m.channel);
      event.data = const_cast<uint8_t*>(m.payload);
      if (lcm_eventlog_write_event(log, &event) == 0) ++logged;
      else ++write_errors;
    });
    const auto now = std::chrono::steady_clock::now();
    if (stopping || now - last_flush >= std::chrono::milliseconds(flush_ms)) {
      std::fflush(log->f);
      last_flush = now;
    }
    if (stopping) break;
  }
  lcm_eventlog_destroy(log);
  close(sock);
  if (fragments > 0 || write_errors > 0)
    std::fprintf(stderr, "t1-lcm-logger: %lld events, %lld fragmented messages skipped, %lld write errors\n",
                 static_cast<long long>(logged), static_cast<long long>(fragments),
                 static_cast<long long>(write_errors));
  return write_errors > 0 ? kExitRuntime : 0;
}
