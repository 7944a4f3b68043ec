// t1rt_bench_mlp: latency of the runtime's MLP (t1rt::Mlp, the kernel variant dispatched for this CPU or the
// portable one) on a policy artifact, next
// to the memory-bandwidth bound of its weights measured in the same process:
//   - streaming read bandwidth over a buffer several times the last-level cache (DRAM-resident weights),
//   - read bandwidth over a buffer the size of the weights, re-read back to back (weights warm in whatever
//     cache level holds them: L2 if they fit, else the LLC),
//   - read bandwidth over half the L2 (the L2-resident bound, reachable only if the weights fit in L2),
// and the latency of one forward pass after the caches were flushed (the "cold" case).
// Prints one JSON line (parsed by tests/bench/runtime_bench.py), including the action for the given input
// so the caller can check it against onnxruntime before trusting the timings.
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "t1rt/artifact.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/policy.hpp"

namespace {
using t1rt::bench::Args;
using t1rt::bench::usage_error;

constexpr std::size_t kFallbackLlcBytes = 32u << 20;  // when sysconf does not know the L3 size
constexpr std::size_t kFallbackL2Bytes = 1u << 20;
constexpr std::size_t kStreamLlcMultiple = 4;  // DRAM buffer = 4 x LLC: nothing of it stays cached
constexpr std::size_t kMinStreamBytes = 64u << 20;
constexpr int kBandwidthRepeats = 5;           // best of N passes (least disturbed by neighbours)
constexpr double kCacheReadTargetBytes = 4e9;  // bytes re-read for the cache-resident bandwidth
constexpr int kWarmupPasses = 100;
constexpr int kMaxCacheIndex = 8;           // sysfs cache/indexN entries looked at
constexpr std::size_t kL2ProbeDivisor = 2;  // L2 probe buffer = half the L2: surely resident

const char* kHelp =
    "usage: t1rt_bench_mlp --policy PATH --input FILE [--iterations N] [--cold-iterations N] [--portable]\n"
    "  --policy PATH          policy artifact (*.safetensors)\n"
    "  --input FILE           raw little-endian float32 network input, obs_size values (normalised obs)\n"
    "  --iterations N         timed back-to-back forward passes (default 20000; 0 = print the action only)\n"
    "  --cold-iterations N    forward passes each after a cache flush (default 100; 0 = skip)\n"
    "  --portable             the portable kernel instead of the one dispatched for this CPU\n"
    "prints one JSON line: kernel variant, latency [ns] median/p99/max, weight bytes, bandwidths [GB/s], bounds [ns],\n"
    "action\n";

// Size of the level-`level` data/unified cache of CPU 0 as the kernel reports it in sysfs (in a VM, sysconf
// may report the host's caches instead), else sysconf, else `fallback`.
std::size_t cache_bytes(int level, int sysconf_name, std::size_t fallback) {
  for (int index = 0; index < kMaxCacheIndex; ++index) {
    const std::string dir = "/sys/devices/system/cpu/cpu0/cache/index" + std::to_string(index) + "/";
    std::ifstream level_file(dir + "level"), type_file(dir + "type"), size_file(dir + "size");
    int found_level = 0;
    std::string type, size;
    if (!(level_file >> found_level) || !(type_file >> type) || !(size_file >> size)) break;
    if (found_level != level || type == "Instruction" || size.empty()) continue;
    std::size_t bytes = std::stoul(size);
    const char unit = size.back();
    if (unit == 'K') bytes <<= 10;
    if (unit == 'M') bytes <<= 20;
    return bytes;
  }
  const long v = sysconf(sysconf_name);
  return v > 0 ? static_cast<std::size_t>(v) : fallback;
}

// Sum of 64-bit words: the compiler vectorises it, so this is the read bandwidth the core can reach.
uint64_t read_sum(const uint64_t* data, std::size_t words) {
  uint64_t a = 0, b = 0, c = 0, d = 0;
  std::size_t i = 0;
  for (; i + 4 <= words; i += 4) {
    a += data[i];
    b += data[i + 1];
    c += data[i + 2];
    d += data[i + 3];
  }
  for (; i < words; ++i) a += data[i];
  return a + b + c + d;
}

volatile uint64_t g_sink = 0;  // keeps the sums alive

// Best read bandwidth [bytes/s] over `bytes`, each measurement re-reading the buffer `passes` times.
double read_bandwidth(const std::vector<uint64_t>& buf, int passes) {
  double best_s = 1e30;
  for (int r = 0; r < kBandwidthRepeats; ++r) {
    const int64_t t0 = t1rt::monotonic_ns();
    uint64_t s = 0;
    for (int p = 0; p < passes; ++p) s += read_sum(buf.data(), buf.size());
    const int64_t t1 = t1rt::monotonic_ns();
    g_sink = g_sink + s;
    best_s = std::min(best_s, static_cast<double>(t1 - t0) * 1e-9);
  }
  return static_cast<double>(buf.size() * sizeof(uint64_t)) * passes / best_s;
}

// Best copy bandwidth [bytes moved/s: read + write] from one half of `buf` to the other.
double copy_bandwidth(std::vector<uint64_t>& buf) {
  const std::size_t half = buf.size() / 2;
  double best_s = 1e30;
  for (int r = 0; r < kBandwidthRepeats; ++r) {
    const int64_t t0 = t1rt::monotonic_ns();
    std::memcpy(buf.data() + half, buf.data(), half * sizeof(uint64_t));
    const int64_t t1 = t1rt::monotonic_ns();
    g_sink = g_sink + buf[half + static_cast<std::size_t>(r)];
    best_s = std::min(best_s, static_cast<double>(t1 - t0) * 1e-9);
  }
  return 2.0 * static_cast<double>(half * sizeof(uint64_t)) / best_s;
}

Eigen::VectorXf read_input(const std::string& path, int size) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open --input file " + path);
  Eigen::VectorXf v(size);
  in.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(size * sizeof(float)));
  if (in.gcount() != static_cast<std::streamsize>(size * sizeof(float)) || in.peek() != EOF)
    throw std::runtime_error("--input " + path + " must hold exactly obs_size = " + std::to_string(size) +
                             " float32 values");
  return v;
}
}  // namespace

int main(int argc, char** argv) {
  std::string policy_path, input_path;
  int iterations = 20000, cold_iterations = 100;
  bool portable = false;
  Args args(argc, argv);
  while (args.next()) {
    const std::string f = args.flag();
    if (f == "--help" || f == "-h") {
      std::fputs(kHelp, stdout);
      return 0;
    } else if (f == "--policy") policy_path = args.value();
    else if (f == "--input") input_path = args.value();
    else if (f == "--iterations") iterations = static_cast<int>(args.number(0));
    else if (f == "--cold-iterations") cold_iterations = static_cast<int>(args.number(0));
    else if (f == "--portable") portable = true;
    else usage_error(argv[0], "unknown argument '" + f + "'");
  }
  if (policy_path.empty() || input_path.empty()) usage_error(argv[0], "--policy and --input are required");

  try {
    const t1rt::PolicyArtifact artifact = t1rt::load_artifact(policy_path);
    const Eigen::VectorXf input = read_input(input_path, artifact.obs_size);
    t1rt::Mlp mlp(artifact, portable ? t1rt::mlp_kernel::portable_variant() : t1rt::mlp_kernel::selected_variant());
    std::size_t weight_bytes = 0;
    std::string shape = std::to_string(artifact.obs_size);
    for (const auto& l : artifact.layers) {
      weight_bytes += static_cast<std::size_t>(l.weight.size() + l.bias.size()) * sizeof(float);
      shape += "-" + std::to_string(l.weight.rows());
    }

    const Eigen::VectorXf action = mlp.run(input);  // the value checked against onnxruntime
    std::string out = "\"variant\": \"" + std::string(mlp.variant_name()) + "\", ";
    auto append_action = [&] {
      out += "\"action\": [";
      for (Eigen::Index i = 0; i < action.size(); ++i) {
        char buf[32];
        std::snprintf(buf, sizeof(buf), "%s%.9g", i ? ", " : "", static_cast<double>(action[i]));
        out += buf;
      }
      out += "]";
    };
    if (iterations == 0) {  // check-only: the action, no timing
      append_action();
      t1rt::bench::json_print(out);
      return 0;
    }
    for (int i = 0; i < kWarmupPasses; ++i) mlp.run(input);
    std::vector<double> warm_ns(static_cast<std::size_t>(iterations));
    for (auto& sample : warm_ns) {
      const int64_t t0 = t1rt::monotonic_ns();
      g_sink = g_sink + static_cast<uint64_t>(mlp.run(input)[0] > 0.0f);
      sample = static_cast<double>(t1rt::monotonic_ns() - t0);
    }

    const std::size_t llc = cache_bytes(3, _SC_LEVEL3_CACHE_SIZE, kFallbackLlcBytes);
    const std::size_t l2 = cache_bytes(2, _SC_LEVEL2_CACHE_SIZE, kFallbackL2Bytes);
    std::vector<uint64_t> stream(std::max(kStreamLlcMultiple * llc, kMinStreamBytes) / sizeof(uint64_t), 1);
    std::vector<uint64_t> weights_sized(weight_bytes / sizeof(uint64_t), 1);
    std::vector<uint64_t> l2_probe(l2 / kL2ProbeDivisor / sizeof(uint64_t), 1);
    const double dram_read = read_bandwidth(stream, 1);
    const double dram_copy = copy_bandwidth(stream);
    const int cache_passes = static_cast<int>(kCacheReadTargetBytes / static_cast<double>(weight_bytes)) + 1;
    read_sum(weights_sized.data(), weights_sized.size());  // bring it into the cache first
    const double cache_read = read_bandwidth(weights_sized, cache_passes);
    read_sum(l2_probe.data(), l2_probe.size());
    const int l2_passes = static_cast<int>(kCacheReadTargetBytes / static_cast<double>(l2 / kL2ProbeDivisor)) + 1;
    const double l2_read = read_bandwidth(l2_probe, l2_passes);

    // Cold: every pass starts after streaming over the whole big buffer, so the weights come from DRAM.
    std::vector<double> cold_ns(static_cast<std::size_t>(cold_iterations));
    for (auto& sample : cold_ns) {
      g_sink = g_sink + read_sum(stream.data(), stream.size());
      const int64_t t0 = t1rt::monotonic_ns();
      g_sink = g_sink + static_cast<uint64_t>(mlp.run(input)[0] > 0.0f);
      sample = static_cast<double>(t1rt::monotonic_ns() - t0);
    }

    out += "\"policy\": \"" + t1rt::bench::json_escape(policy_path) + "\", \"shape\": \"" + shape + "\", ";
    out += "\"activation\": \"" + std::string(artifact.activation == t1rt::Activation::kSwish ? "swish" : "other") +
           "\", ";
    t1rt::bench::json_summary(out, "warm_ns", t1rt::bench::summarize(warm_ns));
    t1rt::bench::json_summary(out, "cold_ns", t1rt::bench::summarize(cold_ns));
    t1rt::bench::json_number(out, "weight_bytes", static_cast<double>(weight_bytes));
    t1rt::bench::json_number(out, "l2_bytes", static_cast<double>(l2));
    t1rt::bench::json_number(out, "llc_bytes", static_cast<double>(llc));
    t1rt::bench::json_number(out, "stream_bytes", static_cast<double>(stream.size() * sizeof(uint64_t)));
    t1rt::bench::json_number(out, "dram_read_GBps", dram_read * 1e-9);
    t1rt::bench::json_number(out, "dram_copy_GBps", dram_copy * 1e-9);
    t1rt::bench::json_number(out, "cache_read_GBps", cache_read * 1e-9);
    t1rt::bench::json_number(out, "l2_read_GBps", l2_read * 1e-9);
    t1rt::bench::json_number(out, "l2_bound_ns", static_cast<double>(weight_bytes) / l2_read * 1e9);
    t1rt::bench::json_number(out, "dram_bound_ns", static_cast<double>(weight_bytes) / dram_read * 1e9);
    t1rt::bench::json_number(out, "cache_bound_ns", static_cast<double>(weight_bytes) / cache_read * 1e9);
    append_action();
    t1rt::bench::json_print(out);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
    return t1rt::bench::kExitRun;
  }
  return 0;
}
