// Fixed-rate task on absolute deadlines (CLOCK_MONOTONIC, TIMER_ABSTIME), after MIT Cheetah-Software's
// PeriodicTask: wake-up lateness and compute time are measured every tick, without heap use.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "t1rt/constants.hpp"

namespace t1rt {

int64_t monotonic_ns();
inline double ns_to_s(int64_t ns) { return static_cast<double>(ns) * 1e-9; }
inline double monotonic_s() { return ns_to_s(monotonic_ns()); }  // CLOCK_MONOTONIC [s]

// Running statistics of one timing quantity [us]: last, mean and max since start, p99 over the last
// kTimingWindow samples (fixed ring buffer + fixed scratch array: no allocation after construction).
class TimingStats {
 public:
  void add(double value_us);
  double last() const { return last_; }
  double mean() const { return count_ ? sum_ / static_cast<double>(count_) : 0.0; }
  double max() const { return max_; }
  int64_t count() const { return count_; }
  double p99();  // not const: sorts into the scratch buffer

 private:
  std::array<float, kTimingWindow> ring_{};
  std::array<float, kTimingWindow> scratch_{};
  std::size_t next_ = 0;
  int64_t count_ = 0;
  double last_ = 0.0, sum_ = 0.0, max_ = 0.0;
};

// Optional real-time setup (--rt). Each step reports its own result; none is fatal here, the caller
// decides (t1-runtime --rt-required turns any failure into exit code 5).
struct RtOptions {
  int cpu = 1;             // core to pin the loop thread to (-1: no pinning)
  int fifo_priority = 80;  // SCHED_FIFO priority
};
class RtSetup {
 public:
  ~RtSetup();
  // Returns one line per step ("ok: ..." / "FAILED: ..."); all_ok() tells whether every step worked.
  std::vector<std::string> apply(const RtOptions& options);
  bool all_ok() const { return all_ok_; }

 private:
  int dma_latency_fd_ = -1;  // held open: the kernel honours the 0 us request only while it is open
  bool all_ok_ = true;
};

// Every wake-up's lateness in 1 us bins up to kMaxUs (and one bin above), as cyclictest -h keeps it: the whole
// run's worst case and tail, not the status window's. Fixed array: no allocation in the loop.
class LatenessHistogram {
 public:
  static constexpr int kMaxUs = 20000;
  void add(double late_us);
  // {"bin_us": [...], "count": [...]} of the non-empty bins (the last bin is "kMaxUs or more") as JSON text.
  std::string json() const;

 private:
  std::array<uint32_t, kMaxUs + 1> counts_{};
};

class PeriodicTask {
 public:
  explicit PeriodicTask(int64_t period_ns = kLoopPeriodNs) : period_ns_(period_ns) {}
  void start();         // first deadline = now + one period
  int64_t wait_next();  // sleeps to the next absolute deadline, records lateness, returns wake time [ns]
  void end_compute();   // records compute time since the last wake-up
  int64_t overruns() const { return overruns_; }
  TimingStats& lateness() { return lateness_; }
  const LatenessHistogram& histogram() const { return histogram_; }
  TimingStats& compute() { return compute_; }

 private:
  int64_t period_ns_;
  int64_t deadline_ns_ = 0;
  int64_t wake_ns_ = 0;
  int64_t overruns_ = 0;
  TimingStats lateness_, compute_;
  LatenessHistogram histogram_;
};

}  // namespace t1rt
