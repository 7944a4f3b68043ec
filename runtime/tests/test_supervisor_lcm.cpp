// Every supervisor rule, driven by real LCM messages: the test plays the simulator through LcmPeer, the
// runtime runs its normal lockstep (or realtime) path and answers on T1_JOINT_CMD.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>

#include "lcm_peer.hpp"
#include "t1_motor_protocol.h"
#include "t1rt/controller.hpp"
#include "t1rt/prepare_gains.hpp"
#include "test_artifact.hpp"
#include "test_keys.hpp"

using namespace t1rt;
using namespace t1rt::testing;

namespace {
constexpr int kKnee = 14, kHipPitch = 11;
constexpr int64_t kTickUs = 2000;
constexpr int kReloadLivenessS = 10;  // a reload's result within this [s] (not a timing check)

// A policy whose action is 0 everywhere but the left knee (tanh(20) = 1, scaled by the largest allowed
// 1.5 rad from a 1.0 rad default): a constant target beyond the joint range that exercises the clamps.
// Knee kp 10 so the torque clamp does not bind before the range.
ArtifactSpec clamp_spec() {
  ArtifactSpec s = make_spec({8});
  for (auto& kv : s.tensors)
    if (kv.first.rfind("layers.", 0) == 0) std::fill(kv.second.data.begin(), kv.second.data.end(), 0.0f);
  s.tensors["layers.1.bias"].data[kKnee] = 20.0f;
  std::vector<float> scale(kJoints, 0.5f);
  scale[kKnee] = static_cast<float>(kMaxActionScaleRad);
  s.meta["action_scale"] = scale;
  s.meta["default_pose"][kKnee] = 1.0;
  s.meta["kp"][kKnee] = 10.0;
  return s;
}

class SupervisorLcm : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(peer_.ok()) << "LCM peer could not start: run inside tools/netns";
    SetUpController(ClockMode::kLockstep);
  }
  void SetUpController(ClockMode clock) {
    ControllerOptions opt;
    opt.policy_path = write_spec("supervisor", clamp_spec());
    opt.lcm_url = resolve_lcm_url("");
    opt.clock = clock;
    opt.quiet = true;
    opt.safety.prepare_duration_s = 0.02;  // 10 ticks: keeps the tests short
    opt.auth = AuthMode::kSigned;          // the operator signs (test_command_auth.cpp: everyone else)
    opt.keys = ring_ = test_ring("supervisor", {test_sender(1, 0x11)});
    opt.approvals_path = approvals_ = own_path("supervisor", ".approvals");
    std::ofstream(approvals_, std::ios::trunc);
    peer_.sign_with(ring_);
    ctrl_ = std::make_unique<Controller>(opt, std::make_unique<PolicyEngine>(load_artifact(opt.policy_path)));
    std::string error;
    ASSERT_TRUE(ctrl_->open(&error)) << error;
    pose_ = ctrl_->policy().artifact().default_pose;
  }
  // One lockstep exchange: IMU stamped imu_utime (< 0: not sent), state k at sim time k*2 ms.
  const t1::joint_command_t& step(int64_t imu_utime = -2, bool send_state = true) {
    ++k_;
    const int64_t now = k_ * kTickUs;
    if (imu_utime != -1) {
      t1::imu_t imu{};
      imu.utime = imu_utime == -2 ? now : imu_utime;
      imu.seq = ++imu_seq_;
      imu.quat[0] = 1.0f;
      peer_.publish(t1::CH_IMU, imu);
    }
    t1::joint_state_t js{};
    js.utime = now;
    js.seq = k_ + seq_skip_;
    std::copy(pose_.begin(), pose_.end(), js.q);
    std::copy(dq_.begin(), dq_.end(), js.dq);
    std::copy(status_.begin(), status_.end(), js.motor_status);
    if (send_state) peer_.publish(t1::CH_JOINT_STATE, js);
    EXPECT_TRUE(ctrl_->step_lockstep(500)) << "no state reached the runtime";
    EXPECT_TRUE(peer_.wait_command(js.seq)) << "no T1_JOINT_CMD answered state " << js.seq;
    return peer_.last_cmd;
  }
  void to_policy() {
    peer_.command("set_mode", "damping");
    step();
    peer_.command("set_mode", "prepare");
    step();
    ASSERT_EQ(ctrl_->supervisor().mode(), Mode::kPrepare);
    for (int i = 0; i < 12; ++i) step();
    peer_.command("set_mode", "policy");
    step();
    ASSERT_EQ(ctrl_->supervisor().mode(), Mode::kPolicy);
  }
  Mode mode() { return ctrl_->supervisor().mode(); }

  // Lockstep ticks until done() (the reload worker's result), within a liveness bound of wall time: the
  // worker runs on its own thread, so no number of ticks is enough on a loaded machine.
  template <class Done>
  void step_until(Done done) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(kReloadLivenessS);
    while (!done() && std::chrono::steady_clock::now() < deadline) step();
  }
  // load_policy of an artifact written by write_spec: approved by the operator, sent by its name in the folder.
  void load_policy(const std::string& name, const ArtifactSpec& spec) {
    const std::string path = write_spec(name, spec);
    approve(*ring_, 0, approvals_, path);
    peer_.command("load_policy", path.substr(path.rfind('/') + 1));
  }

  LcmPeer peer_;
  std::shared_ptr<const KeyRing> ring_;
  std::string approvals_;
  std::unique_ptr<Controller> ctrl_;
  JointArray pose_{}, dq_{};
  std::array<int32_t, kJoints> status_{};
  int64_t k_ = 0, imu_seq_ = 0, seq_skip_ = 0;
};
}  // namespace

TEST_F(SupervisorLcm, StartsPassiveWithZeroTorqueAndAnswersStateSeq) {
  const auto& c = step();
  EXPECT_EQ(c.mode, t1::joint_command_t::MODE_PASSIVE);
  EXPECT_EQ(c.state_seq, k_);
  for (std::size_t i = 0; i < kJoints; ++i) EXPECT_EQ(c.kp[i] + c.kd[i] + c.tau_ff[i], 0.0f);
}

TEST_F(SupervisorLcm, PrepareHoldsWithStandUpGainsPolicyWithArtifactGains) {
  peer_.command("set_mode", "damping");
  step();
  peer_.command("set_mode", "prepare");
  step();
  const auto& p = step();
  ASSERT_EQ(p.mode, t1::joint_command_t::MODE_PREPARE);
  for (std::size_t i = 0; i < kJoints; ++i) {  // the robot's prepare gains, not the artifact's (40 / 10 / 2)
    EXPECT_FLOAT_EQ(p.kp[i], kPrepareKp[i]) << i;
    EXPECT_FLOAT_EQ(p.kd[i], kPrepareKd[i]) << i;
  }
  for (int i = 0; i < 12; ++i) step();
  peer_.command("set_mode", "policy");
  step();
  ASSERT_EQ(mode(), Mode::kPolicy);
  const auto& c = step();
  EXPECT_EQ(c.mode, t1::joint_command_t::MODE_POLICY);
  EXPECT_FLOAT_EQ(c.kp[0], 40.0f);
  EXPECT_FLOAT_EQ(c.kd[0], 2.0f);
  EXPECT_GT(ctrl_->policy_ticks(), 0);
}

TEST_F(SupervisorLcm, StaleImuHoldsThenFaults) {
  to_policy();
  const int64_t imu_time = (k_ + 1) * kTickUs;
  step(imu_time);
  step(-1);                                  // no new IMU from here on
  for (int i = 0; i < 4; ++i) step(-1);      // age 10 ms: still fresh
  const float held = step(-1).q_des[kKnee];  // age > 10 ms: hold
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kImuHold);
  EXPECT_EQ(step(-1).q_des[kKnee], held);
  EXPECT_EQ(mode(), Mode::kPolicy);
  for (int i = 0; i < 20; ++i) step(-1);  // > 50 ms
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kImuStale);
  EXPECT_EQ(peer_.last_cmd.mode, t1::joint_command_t::MODE_FAULT);
  EXPECT_EQ(peer_.last_cmd.kp[kKnee], 0.0f);
  EXPECT_GT(peer_.last_cmd.kd[kKnee], 0.0f);
}

TEST_F(SupervisorLcm, SequenceGapsCounted) {
  step();
  seq_skip_ = 3;  // states k+3...: 3 missing
  step();
  imu_seq_ += 5;  // 5 IMU samples lost
  step();
  EXPECT_EQ(ctrl_->supervisor().joint_seq().gaps(), 3);
  EXPECT_EQ(ctrl_->supervisor().imu_seq().gaps(), 5);
}

// The transport reads the LCM group itself (messages/cpp/t1_lcm_group.hpp): a datagram that does not decode,
// and a message too large for one datagram (LCM sends it in fragments, which it does not reassemble), are
// counted and leave the live state as it was; the next state is answered.
TEST_F(SupervisorLcm, TruncatedAndFragmentedStatesCountedAndIgnored) {
  step();
  const float q0 = ctrl_->transport().joint.msg.q[0];
  const int64_t errors = ctrl_->transport().decode_errors;
  t1::joint_state_t js{};
  js.seq = 1000;
  js.q[0] = q0 + 1.0f;
  std::vector<uint8_t> buf(js.getEncodedSize());
  js.encode(buf.data(), 0, static_cast<int>(buf.size()));
  peer_.publish_raw(t1::CH_JOINT_STATE, buf.data(), buf.size() - 4);  // truncated
  buf.resize(100 * 1024);                                             // trailing bytes, over 64 kB
  peer_.publish_raw(t1::CH_JOINT_STATE, buf.data(), buf.size());
  step();
  EXPECT_EQ(ctrl_->transport().decode_errors, errors + 2);
  EXPECT_FLOAT_EQ(ctrl_->transport().joint.msg.q[0], q0);
  EXPECT_EQ(ctrl_->transport().joint.msg.seq, k_);
}

TEST_F(SupervisorLcm, NanInStateFaults) {
  to_policy();
  pose_[3] = NAN;
  EXPECT_EQ(step().mode, t1::joint_command_t::MODE_FAULT);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kNonFiniteState);
}

TEST_F(SupervisorLcm, NanActionFaults) {
  to_policy();
  for (int i = 0; i < kPolicyDecimation; ++i) step();
  ctrl_->policy().inject_nan_action_once();
  for (int i = 0; i < kPolicyDecimation && mode() == Mode::kPolicy; ++i) step();
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kNonFiniteAction);
  EXPECT_STREQ(ctrl_->supervisor().last_fault(), "non-finite action");
}

TEST_F(SupervisorLcm, TargetsRateLimitedAndClampedToRange) {
  to_policy();
  const SafetyConfig cfg;
  const float hi = 0.5f * (T1_MOTORS[kKnee].q_min_rad + T1_MOTORS[kKnee].q_max_rad) +
                   0.5f * (T1_MOTORS[kKnee].q_max_rad - T1_MOTORS[kKnee].q_min_rad) * cfg.joint_range_fraction;
  float prev = peer_.last_cmd.q_des[kKnee];
  for (int i = 0; i < 60; ++i) {
    const float now = step().q_des[kKnee];
    EXPECT_LE(now - prev, cfg.max_target_step_rad + 1e-6f) << "tick " << i;
    EXPECT_LE(now, hi + 1e-6f);
    prev = now;
  }
  EXPECT_NEAR(prev, hi, 1e-5);  // the raw target (1.0 + 1.5 rad) is beyond the range: it ends at 95 %
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kTargetClamped);
}

// Rule R6: the rate limit is never broken; the expected torque comes down to the motor limit as fast as
// the rate allows and then stays within it.
TEST_F(SupervisorLcm, ExpectedTorqueClampedByMovingTarget) {
  to_policy();
  for (int i = 0; i < 30; ++i) {  // far from the target: kp 40 * 1.5 rad = 60 N·m > 45 N·m, reached at 25 rad/s
    pose_[kHipPitch] += 0.05f;    // (a jump there in one reply would be rule R10's impossible reading)
    step();
  }
  dq_[kHipPitch] = 2.0f;
  const SafetyConfig cfg;
  const float limit = T1_MOTORS[kHipPitch].torque_limit_nm;
  float prev = peer_.last_cmd.q_des[kHipPitch], prev_excess = INFINITY;
  bool within = false;
  for (int i = 0; i < 40; ++i) {
    const auto& c = step();
    const float tau = c.kp[kHipPitch] * (c.q_des[kHipPitch] - pose_[kHipPitch]) - c.kd[kHipPitch] * dq_[kHipPitch];
    EXPECT_LE(std::fabs(c.q_des[kHipPitch] - prev), cfg.max_target_step_rad + 1e-5f) << "tick " << i;
    const float excess = std::fabs(tau) - limit;
    EXPECT_LE(excess, std::max(prev_excess, 1e-3f)) << "tick " << i;  // never moves away from the limit
    if (within) EXPECT_LE(excess, 1e-3f) << "tick " << i;
    within = within || excess <= 1e-3f;
    prev = c.q_des[kHipPitch], prev_excess = excess;
  }
  EXPECT_TRUE(within);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kTorqueClamped);
}

TEST_F(SupervisorLcm, MotorFaultBitsFault) {
  to_policy();
  status_[5] = T1_STATUS_OVER_LIMIT;  // saturation is expected in falls: information only
  EXPECT_EQ(step().mode, t1::joint_command_t::MODE_POLICY);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kMotorOverLimit);
  status_[5] = T1_STATUS_WATCHDOG;
  EXPECT_EQ(step().mode, t1::joint_command_t::MODE_FAULT);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kMotorFault);
  EXPECT_NE(std::string(ctrl_->supervisor().last_fault()).find("Left_Elbow_Yaw"), std::string::npos);
}

TEST_F(SupervisorLcm, EstopDampsWithinOneTick) {
  to_policy();
  peer_.command("estop");
  const auto& c = step();  // the very next command
  EXPECT_EQ(c.mode, t1::joint_command_t::MODE_DAMPING);
  for (std::size_t i = 0; i < kJoints; ++i) {
    EXPECT_EQ(c.kp[i], 0.0f);
    EXPECT_FLOAT_EQ(c.kd[i], T1_MOTORS[i].d_safe_nms);
  }
}

TEST_F(SupervisorLcm, FaultLeavesOnlyOnReset) {
  to_policy();
  pose_[0] = NAN;
  step();
  pose_[0] = 0.0f;
  for (const char* m : {"damping", "prepare", "policy", "passive"}) {
    peer_.command("set_mode", m);
    EXPECT_EQ(step().mode, t1::joint_command_t::MODE_FAULT) << m;
  }
  peer_.command("estop");
  EXPECT_EQ(step().mode, t1::joint_command_t::MODE_FAULT);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(step().mode, t1::joint_command_t::MODE_FAULT);
  peer_.command("reset");
  EXPECT_EQ(step().mode, t1::joint_command_t::MODE_DAMPING);
  EXPECT_EQ(ctrl_->supervisor().fault_bits() & 0xFFFF, 0);
}

TEST_F(SupervisorLcm, StaleJoystickZeroesCommand) {
  to_policy();
  t1::joystick_t js{};
  js.utime = (k_ + 1) * kTickUs;
  js.vx = 0.8f;
  peer_.publish_signed(t1::CH_JOYSTICK, js);
  for (int i = 0; i < kPolicyDecimation; ++i) step();
  constexpr int kCommandIndex = 6;  // gyro 3, gravity 3, then command
  EXPECT_FLOAT_EQ(ctrl_->policy().obs_raw()[kCommandIndex], 0.8f);
  for (int i = 0; i < 130; ++i) step();  // 260 ms of sim time > 250 ms
  for (int i = 0; i < kPolicyDecimation; ++i) step();
  EXPECT_FLOAT_EQ(ctrl_->policy().obs_raw()[kCommandIndex], 0.0f);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kJoystickStale);
}

TEST_F(SupervisorLcm, HotReloadRejectsBadFileAndSwapsGoodOne) {
  to_policy();
  const std::string old_hash = ctrl_->policy().artifact().content_hash;
  ArtifactSpec bad = clamp_spec();
  bad.meta["control_dt"] = 0.01;
  load_policy("reload_bad", bad);
  step_until([&] { return !ctrl_->reload_message().empty(); });
  EXPECT_NE(ctrl_->reload_message().find("control_dt"), std::string::npos) << ctrl_->reload_message();
  for (int i = 0; i < 60; ++i) step();
  EXPECT_EQ(ctrl_->policy().artifact().content_hash, old_hash);
  EXPECT_EQ(mode(), Mode::kPolicy);
  peer_.drain();
  ASSERT_GT(peer_.statuses, 0);
  EXPECT_NE(peer_.last_status.info.find("REJECTED"), std::string::npos) << peer_.last_status.info;
  EXPECT_NE(peer_.last_status.info.find("control_dt"), std::string::npos) << peer_.last_status.info;

  ArtifactSpec good = clamp_spec();
  good.meta["name"] = "reloaded";
  load_policy("reload_good", good);
  step_until([&] {  // the status says "reload ok" only beside the new policy's name
    peer_.drain();
    const bool ok = peer_.last_status.info.find("reload ok") != std::string::npos;
    if (ok) EXPECT_EQ(peer_.last_status.policy_name, "reloaded") << peer_.last_status.info;
    return ok;
  });
  EXPECT_EQ(ctrl_->policy().artifact().name, "reloaded");
  EXPECT_EQ(mode(), Mode::kPolicy);
}

// Realtime clock: joint states stop while the IMU keeps coming; ages use CLOCK_MONOTONIC receive time.
TEST_F(SupervisorLcm, StaleJointsFaultInRealtime) {
  ctrl_.reset();
  SetUpController(ClockMode::kRealtime);
  ctrl_->task().start();
  auto rt_step = [&](bool joints) {
    t1::imu_t imu{};
    imu.quat[0] = 1.0f;
    imu.seq = ++imu_seq_;
    peer_.publish(t1::CH_IMU, imu);
    if (joints) {
      t1::joint_state_t js{};
      js.seq = ++k_;
      std::copy(pose_.begin(), pose_.end(), js.q);
      peer_.publish(t1::CH_JOINT_STATE, js);
    }
    ctrl_->step_realtime();
  };
  ctrl_->supervisor().request_mode(Mode::kDamping);
  rt_step(true);
  ctrl_->supervisor().request_mode(Mode::kPrepare);
  rt_step(true);
  ASSERT_EQ(mode(), Mode::kPrepare);
  for (int i = 0; i < 12; ++i) rt_step(true);
  ctrl_->supervisor().request_mode(Mode::kPolicy);
  const double last_joints_s = monotonic_s();  // the last joint frame is sent and received after this
  rt_step(true);
  ASSERT_EQ(mode(), Mode::kPolicy);
  int ticks = 0;
  while (mode() == Mode::kPolicy && ticks < 100) rt_step(false), ++ticks;
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_TRUE(ctrl_->supervisor().fault_bits() & fault_bit::kJointStale) << ctrl_->supervisor().last_fault();
  // Ages are wall time in realtime mode: it faults only once the joints are older than the fault age
  // (holding before), however many ticks a loaded machine managed in that time.
  EXPECT_GE(monotonic_s() - last_joints_s, SafetyConfig{}.fault_age_s);
}

// Rule R3 bookkeeping on its own: late frames take their gap back, duplicates and late frames are
// counted as reordered and rejected, a frame far behind is a publisher restart.
TEST(SeqTracker, RejectsOlderFramesAndCountsOnlyRealGaps) {
  SeqTracker t;
  EXPECT_TRUE(t.accept(10));
  EXPECT_TRUE(t.accept(12));   // 11 missing so far
  EXPECT_FALSE(t.accept(11));  // late: rejected, and not a gap any more
  EXPECT_FALSE(t.accept(12));  // duplicate
  EXPECT_TRUE(t.accept(15));   // 13, 14 really lost
  EXPECT_EQ(t.gaps(), 2);
  EXPECT_EQ(t.reordered(), 2);
  EXPECT_TRUE(t.accept(100));  // 16..99 lost
  EXPECT_EQ(t.gaps(), 86);
  EXPECT_FALSE(t.accept(100 - SeqTracker::kWindowFrames + 1));  // oldest in the window: late, its gap taken back
  EXPECT_EQ(t.gaps(), 85);
  EXPECT_TRUE(t.accept(20));  // further behind: the publisher restarted
  EXPECT_TRUE(t.accept(21));
  EXPECT_EQ(t.gaps(), 85);
  EXPECT_EQ(t.reordered(), 3);
}
