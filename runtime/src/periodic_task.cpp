#include "t1rt/periodic_task.hpp"

#include <fcntl.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace t1rt {

namespace {
constexpr int64_t kNsPerS = 1'000'000'000;
constexpr double kNsPerUs = 1000.0;
constexpr double kP99 = 0.99;
constexpr std::size_t kPrefaultStackBytes = 512 * 1024;  // the loop thread's stack touched at start
constexpr std::size_t kPageBytes = 4096;

// Touches kPrefaultStackBytes of this thread's stack, so under mlockall its pages are resident before the loop.
__attribute__((noinline)) void prefault_stack() {
  volatile unsigned char stack[kPrefaultStackBytes];
  for (std::size_t i = 0; i < sizeof(stack); i += kPageBytes) stack[i] = 0;
}

timespec to_timespec(int64_t ns) {
  timespec ts;
  ts.tv_sec = static_cast<time_t>(ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(ns % kNsPerS);
  return ts;
}
}  // namespace

int64_t monotonic_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

void TimingStats::add(double value_us) {
  last_ = value_us;
  sum_ += value_us;
  max_ = count_ == 0 ? value_us : std::max(max_, value_us);
  ++count_;
  ring_[next_] = static_cast<float>(value_us);
  next_ = (next_ + 1) % ring_.size();
}

double TimingStats::p99() {
  const std::size_t n = static_cast<std::size_t>(std::min<int64_t>(count_, static_cast<int64_t>(ring_.size())));
  if (n == 0) return 0.0;
  std::copy(ring_.begin(), ring_.begin() + static_cast<std::ptrdiff_t>(n), scratch_.begin());
  const std::size_t k = std::min(n - 1, static_cast<std::size_t>(kP99 * static_cast<double>(n)));
  std::nth_element(scratch_.begin(), scratch_.begin() + static_cast<std::ptrdiff_t>(k),
                   scratch_.begin() + static_cast<std::ptrdiff_t>(n));
  return scratch_[k];
}

void LatenessHistogram::add(double late_us) {
  const double clamped = std::min(std::max(late_us, 0.0), static_cast<double>(kMaxUs));
  ++counts_[static_cast<std::size_t>(clamped)];
}

std::string LatenessHistogram::json() const {
  std::string bins, counts;
  for (std::size_t us = 0; us < counts_.size(); ++us) {
    if (!counts_[us]) continue;
    bins += (bins.empty() ? "" : ",") + std::to_string(us);
    counts += (counts.empty() ? "" : ",") + std::to_string(counts_[us]);
  }
  return "{\"bin_us\": [" + bins + "], \"count\": [" + counts + "]}";
}

RtSetup::~RtSetup() {
  if (dma_latency_fd_ >= 0) close(dma_latency_fd_);
}

std::vector<std::string> RtSetup::apply(const RtOptions& options) {
  std::vector<std::string> report;
  auto step = [&](bool ok, const std::string& what) {
    report.push_back((ok ? "ok: " : "FAILED: ") + what + (ok ? "" : std::string(" (") + std::strerror(errno) + ")"));
    all_ok_ = all_ok_ && ok;
  };
  step(mlockall(MCL_CURRENT | MCL_FUTURE) == 0, "mlockall(MCL_CURRENT|MCL_FUTURE)");
  // Freed heap stays with the process (no trim, no separately mmap'd chunks), so a later allocation off the
  // loop (reload, operator commands) never gives pages back to be faulted in again.
  step(mallopt(M_TRIM_THRESHOLD, -1) == 1 && mallopt(M_MMAP_MAX, 0) == 1, "malloc: no trim, no mmap");
  prefault_stack();
  sched_param param{};
  param.sched_priority = options.fifo_priority;
  errno = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  step(errno == 0, "SCHED_FIFO priority " + std::to_string(options.fifo_priority));
  if (options.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(options.cpu, &set);
    errno = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
    step(errno == 0, "pin loop thread to CPU " + std::to_string(options.cpu));
  }
  dma_latency_fd_ = open("/dev/cpu_dma_latency", O_WRONLY);
  bool dma_ok = false;
  if (dma_latency_fd_ >= 0) {
    const int32_t zero_us = 0;
    dma_ok = write(dma_latency_fd_, &zero_us, sizeof(zero_us)) == static_cast<ssize_t>(sizeof(zero_us));
  }
  step(dma_ok, "/dev/cpu_dma_latency = 0 (held open)");
  return report;
}

void PeriodicTask::start() { deadline_ns_ = monotonic_ns() + period_ns_; }

int64_t PeriodicTask::wait_next() {
  const timespec ts = to_timespec(deadline_ns_);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
  wake_ns_ = monotonic_ns();
  const int64_t late_ns = wake_ns_ - deadline_ns_;
  lateness_.add(static_cast<double>(late_ns) / kNsPerUs);
  histogram_.add(static_cast<double>(late_ns) / kNsPerUs);
  deadline_ns_ += period_ns_;
  if (late_ns > period_ns_) {
    // Missed at least one whole period: count it and re-phase instead of bursting to catch up.
    ++overruns_;
    deadline_ns_ = wake_ns_ + period_ns_;
  }
  return wake_ns_;
}

void PeriodicTask::end_compute() { compute_.add(static_cast<double>(monotonic_ns() - wake_ns_) / kNsPerUs); }

}  // namespace t1rt
