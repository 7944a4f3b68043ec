// Small helpers shared by the runtime bench executables: command-line values with clear errors, order
// statistics over recorded samples, and one-line JSON output (read by tests/bench/runtime_bench.py).
#pragma once
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace t1rt::bench {

inline constexpr int kExitUsage = 2;
inline constexpr int kExitRun = 1;

[[noreturn]] inline void usage_error(const char* program, const std::string& problem) {
  std::fprintf(stderr, "%s: %s (see --help)\n", program, problem.c_str());
  std::exit(kExitUsage);
}

// Argument cursor: value() takes the next argv entry or exits naming the flag that lacks one.
class Args {
 public:
  Args(int argc, char** argv) : argc_(argc), argv_(argv) {}
  bool next() { return ++i_ < argc_; }
  std::string flag() const { return argv_[i_]; }
  const char* value() {
    if (i_ + 1 >= argc_) usage_error(argv_[0], std::string(argv_[i_]) + " needs a value");
    return argv_[++i_];
  }
  double number(double min_value) {
    const char* name = argv_[i_];
    const char* text = value();
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (!end || *end || !(v >= min_value))
      usage_error(argv_[0],
                  std::string(name) + " needs a number >= " + std::to_string(min_value) + ", not '" + text + "'");
    return v;
  }
  const char* program() const { return argv_[0]; }

 private:
  int argc_;
  char** argv_;
  int i_ = 0;
};

struct Summary {
  std::size_t count = 0;
  double median = 0.0, p99 = 0.0, max = 0.0, min = 0.0;
};

// Order statistics of `samples` (copied: the caller keeps its recording order). Nearest-rank percentiles.
inline Summary summarize(std::vector<double> samples) {
  Summary s;
  s.count = samples.size();
  if (samples.empty()) return s;
  std::sort(samples.begin(), samples.end());
  auto rank = [&](double q) {
    const std::size_t k = static_cast<std::size_t>(q * static_cast<double>(samples.size() - 1) + 0.5);
    return samples[std::min(k, samples.size() - 1)];
  };
  s.median = rank(0.5);
  s.p99 = rank(0.99);
  s.max = samples.back();
  s.min = samples.front();
  return s;
}

// Appends `"prefix_median": ..., "prefix_p99": ..., ...` to a JSON object under construction.
inline void json_summary(std::string& out, const char* prefix, const Summary& s) {
  char buf[320];
  std::snprintf(buf, sizeof(buf),
                "\"%s_count\": %zu, \"%s_median\": %.4f, \"%s_p99\": %.4f, \"%s_max\": %.4f, \"%s_min\": %.4f, ",
                prefix, s.count, prefix, s.median, prefix, s.p99, prefix, s.max, prefix, s.min);
  out += buf;
}

inline void json_number(std::string& out, const char* key, double v) {
  char buf[128];
  std::snprintf(buf, sizeof(buf), "\"%s\": %.9g, ", key, v);
  out += buf;
}

inline std::string json_escape(const std::string& text) {
  std::string e;
  for (char c : text) {
    if (c == '"' || c == '\\') e += '\\';
    if (static_cast<unsigned char>(c) >= 0x20) e += c;
  }
  return e;
}

// Prints `{...}` from the accumulated "key": value, pairs (trailing comma removed) on one stdout line.
inline void json_print(std::string body) {
  while (!body.empty() && (body.back() == ' ' || body.back() == ',')) body.pop_back();
  std::printf("{%s}\n", body.c_str());
  std::fflush(stdout);
}

}  // namespace t1rt::bench
