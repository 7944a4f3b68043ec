// t1rt_bench_loop: wake-up lateness of the runtime's PeriodicTask at 500 Hz (the loop t1-runtime uses in
// realtime mode), with or without the --rt setup (SCHED_FIFO + mlockall + CPU pinning + cpu_dma_latency).
// Every tick's lateness is recorded (preallocated), so median / p99 / max cover the whole run, not the
// runtime's 2 s status window. Prints one JSON line for tests/bench/runtime_bench.py.
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "t1rt/constants.hpp"
#include "t1rt/periodic_task.hpp"

namespace {
using t1rt::bench::Args;
using t1rt::bench::usage_error;

const char* kHelp =
    "usage: t1rt_bench_loop [--seconds S] [--rt] [--rt-cpu N]\n"
    "  --seconds S   run time (default 60)\n"
    "  --rt          SCHED_FIFO 80, mlockall, pin to --rt-cpu, /dev/cpu_dma_latency = 0 (as t1-runtime --rt)\n"
    "  --rt-cpu N    core for --rt pinning (default 1; -1 = no pinning)\n"
    "prints one JSON line: lateness [us] median/p99/max over every tick, overruns, rt setup report\n";
}  // namespace

int main(int argc, char** argv) {
  double seconds = 60.0;
  bool rt = false;
  t1rt::RtOptions rt_options;
  Args args(argc, argv);
  while (args.next()) {
    const std::string f = args.flag();
    if (f == "--help" || f == "-h") {
      std::fputs(kHelp, stdout);
      return 0;
    } else if (f == "--seconds") seconds = args.number(0.01);
    else if (f == "--rt") rt = true;
    else if (f == "--rt-cpu") rt_options.cpu = static_cast<int>(args.number(-1));
    else usage_error(argv[0], "unknown argument '" + f + "'");
  }

  t1rt::RtSetup rt_setup;  // keeps /dev/cpu_dma_latency open for the whole run
  std::string rt_report;
  if (rt) {
    for (const std::string& line : rt_setup.apply(rt_options)) rt_report += (rt_report.empty() ? "" : "; ") + line;
  }
  const auto ticks = static_cast<std::size_t>(seconds / t1rt::kLoopDtS + 0.5);
  std::vector<double> lateness_us(ticks);  // allocated (and, with mlockall, locked) before the loop

  t1rt::PeriodicTask task;
  task.start();
  for (auto& sample : lateness_us) {
    task.wait_next();
    sample = task.lateness().last();
    task.end_compute();
  }

  std::string out;
  out += std::string("\"mode\": \"") + (rt ? "rt" : "default") + "\", ";
  t1rt::bench::json_number(out, "period_us", t1rt::kLoopDtS * 1e6);
  t1rt::bench::json_summary(out, "lateness_us", t1rt::bench::summarize(lateness_us));
  t1rt::bench::json_number(out, "overruns", static_cast<double>(task.overruns()));
  out += "\"rt_ok\": " + std::string(rt && rt_setup.all_ok() ? "true" : "false") + ", ";
  out += "\"rt_report\": \"" + t1rt::bench::json_escape(rt_report) + "\"";
  t1rt::bench::json_print(out);
  return 0;
}
