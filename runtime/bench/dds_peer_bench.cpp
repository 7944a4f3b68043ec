// t1rt_bench_dds_peer: plays the DDS robot for t1-runtime --transport dds --clock lockstep and measures
// state->command latency over Cyclone DDS: for each k it writes a LowState_ on rt/low_state and waits for
// the next LowCmd_ on rt/joint_ctrl; latency = write of the state -> arrival of the command
// (CLOCK_MONOTONIC). LowState_ has no sequence number, so the runtime answers each state exactly once and
// the first answer after a write is that state's. The twin of t1rt_bench_lcm_peer (same statistics).
// Prints one JSON line for tests/bench/runtime_bench.py.
#include <dds/dds.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "booster_low.h"
#include "t1_contract.hpp"
#include "t1rt/constants.hpp"
#include "t1rt/periodic_task.hpp"

namespace {
using t1rt::bench::Args;
using t1rt::bench::usage_error;
using MotorState = booster_interface_msg_dds__MotorState_;

constexpr float kGravityMps2 = 9.81f;  // accelerometer reading at rest [m/s^2]
constexpr int kConnectRetryMs = 100;   // re-write state 0 until the runtime's reader has matched
constexpr int kSettleMs = 200;         // then absorb the answers to the re-written copies
constexpr int64_t kMsToNs = 1'000'000;
// The encoders move one count per state: still ones under PD torque are a frozen encoder to the runtime
// (rule R9 of runtime/src/safety_supervisor.cpp), which would latch FAULT before POLICY.
constexpr float kEncoderDitherRad = 1e-4f;

const char* kHelp =
    "usage: t1rt_bench_dds_peer [--count N] [--warmup N] [--timeout-ms MS] [--connect-s S]\n"
    "  --count N        recorded exchanges (default 5000)\n"
    "  --warmup N       unrecorded exchanges first (default 2000: past the runtime's 2 s PREPARE into POLICY)\n"
    "  --timeout-ms MS  give up when one command takes longer (default 1000)\n"
    "  --connect-s S    how long to wait for the first answer (default 10)\n"
    "Cyclone config from $CYCLONEDDS_URI (tools/netns: loopback only). Prints one JSON line: latency [us].\n";

struct Peer {
  dds_entity_t participant = 0, writer = 0, reader = 0, waitset = 0;
  std::array<MotorState, t1rt::kJoints> motors{};
  booster_interface_msg_dds__LowState_ state{};
  int64_t writes = 0;

  bool open(std::string* error) {
    participant = dds_create_participant(t1::kDdsDomainId, nullptr, nullptr);
    if (participant < 0) {
      *error = dds_strretcode(participant);
      return false;
    }
    const dds_entity_t st =
        dds_create_topic(participant, &booster_interface_msg_dds__LowState__desc, t1::kDdsStateTopic, nullptr, nullptr);
    const dds_entity_t ct =
        dds_create_topic(participant, &booster_interface_msg_dds__LowCmd__desc, t1::kDdsCommandTopic, nullptr, nullptr);
    dds_qos_t* qos = dds_create_qos();
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
    writer = dds_create_writer(participant, st, qos, nullptr);
    dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);  // count every answer, never overwrite one
    reader = dds_create_reader(participant, ct, qos, nullptr);
    dds_delete_qos(qos);
    if (st < 0 || ct < 0 || writer < 0 || reader < 0) {
      *error = "topic/reader/writer creation failed";
      return false;
    }
    dds_set_status_mask(reader, DDS_DATA_AVAILABLE_STATUS);
    waitset = dds_create_waitset(participant);
    dds_waitset_attach(waitset, reader, reader);
    state.imu_state.acc[2] = kGravityMps2;  // upright, at rest
    state.motor_state_serial._buffer = motors.data();
    state.motor_state_serial._length = state.motor_state_serial._maximum = static_cast<uint32_t>(motors.size());
    state.motor_state_serial._release = false;
    return true;
  }

  // Takes every queued command; returns how many.
  int take() {
    void* samples[16] = {nullptr};
    dds_sample_info_t infos[16];
    int total = 0;
    for (;;) {
      const dds_return_t n = dds_take(reader, samples, infos, 16, 16);
      if (n <= 0) break;
      for (dds_return_t i = 0; i < n; ++i) total += infos[i].valid_data ? 1 : 0;
      dds_return_loan(reader, samples, n);
    }
    return total;
  }

  // Writes one state; returns the latency [us] of the first command after it, negative on timeout.
  double exchange(int timeout_ms) {
    ++writes;
    for (MotorState& m : motors) m.q = static_cast<float>(writes % 2) * kEncoderDitherRad;
    const int64_t t0 = t1rt::monotonic_ns();
    dds_write(writer, &state);
    const int64_t deadline = t0 + timeout_ms * kMsToNs;
    for (;;) {
      if (take() > 0) return static_cast<double>(t1rt::monotonic_ns() - t0) * 1e-3;
      const int64_t left = deadline - t1rt::monotonic_ns();
      if (left <= 0) return -1.0;
      dds_waitset_wait(waitset, nullptr, 0, left);
    }
  }

  bool connect(double connect_s) {
    const int tries = static_cast<int>(connect_s * 1000.0 / kConnectRetryMs) + 1;
    for (int i = 0; i < tries; ++i) {
      if (exchange(kConnectRetryMs) < 0.0) continue;
      const int64_t until = t1rt::monotonic_ns() + kSettleMs * kMsToNs;
      while (t1rt::monotonic_ns() < until) {
        take();
        dds_waitset_wait(waitset, nullptr, 0, DDS_MSECS(10));
      }
      take();
      return true;
    }
    return false;
  }
};
}  // namespace

int main(int argc, char** argv) {
  int count = 5000, warmup = 2000, timeout_ms = 1000;
  double connect_s = 10.0;
  Args args(argc, argv);
  while (args.next()) {
    const std::string f = args.flag();
    if (f == "--help" || f == "-h") {
      std::fputs(kHelp, stdout);
      return 0;
    } else if (f == "--count") count = static_cast<int>(args.number(1));
    else if (f == "--warmup") warmup = static_cast<int>(args.number(0));
    else if (f == "--timeout-ms") timeout_ms = static_cast<int>(args.number(1));
    else if (f == "--connect-s") connect_s = args.number(0.1);
    else usage_error(argv[0], "unknown argument '" + f + "'");
  }
  Peer p;
  std::string error;
  if (!p.open(&error)) {
    std::fprintf(stderr, "%s: DDS set-up failed: %s\n", argv[0], error.c_str());
    return t1rt::bench::kExitRun;
  }
  if (!p.connect(connect_s)) {
    std::fprintf(stderr, "%s: no LowCmd_ answered within %.1f s\n", argv[0], connect_s);
    return t1rt::bench::kExitRun;
  }
  std::vector<double> all_us;
  all_us.reserve(static_cast<std::size_t>(count));
  for (int i = 0; i < warmup + count; ++i) {
    const double us = p.exchange(timeout_ms);
    if (us < 0.0) {
      std::fprintf(stderr, "%s: state %d unanswered after %d ms\n", argv[0], i, timeout_ms);
      return t1rt::bench::kExitRun;
    }
    if (i >= warmup) all_us.push_back(us);
  }
  std::string out;
  t1rt::bench::json_summary(out, "latency_us", t1rt::bench::summarize(all_us));
  t1rt::bench::json_number(out, "warmup_exchanges", warmup);
  t1rt::bench::json_print(out);
  dds_delete(p.participant);
  return 0;
}
