// Whose state the runtime takes: with a robot key (--robot-key) only its robot's signed imu_t / joint_state_t,
// every other frame refused and counted by reason (command_auth.hpp); without one, safety rule R12 names a
// second sequence stream as a FAULT and never adopts it, while a real restart (the old stream silent first)
// is taken as R3 says. Driven over real LCM ($T1_LCM_URL, inside tools/netns), lockstep.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>

#include "lcm_peer.hpp"
#include "t1rt/controller.hpp"
#include "test_artifact.hpp"
#include "test_keys.hpp"

using namespace t1rt;
using namespace t1rt::testing;

namespace {
constexpr float kForgedPitchRad = 70.0f * 3.14159265f / 180.0f;  // the forger's 70 degree pitch
constexpr int kStatusTicks = 60;                                 // more than one status period (10 Hz)

int64_t wall_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

bool says(const std::string& text, const char* what) { return text.find(what) != std::string::npos; }

// A lockstep runtime and the robot beside it (the peer signs state with robot_ring when it is non-null).
class Robot {
 public:
  Robot(const char* name, std::shared_ptr<const KeyRing> robot_ring) : ring_(std::move(robot_ring)) {
    ControllerOptions opt;
    opt.policy_path = write_spec(name, make_spec({64, 64}));
    opt.lcm_url = resolve_lcm_url("");
    opt.clock = ClockMode::kLockstep;
    opt.quiet = true;
    opt.autostart = true;
    opt.safety.prepare_duration_s = 0.02;
    opt.auth = AuthMode::kUnauthenticated;
    opt.robot_keys = ring_;
    ctrl_ = std::make_unique<Controller>(opt, std::make_unique<PolicyEngine>(load_artifact(opt.policy_path)));
    std::string error;
    ok_ = peer_.ok() && ctrl_->open(&error);
    EXPECT_TRUE(ok_) << error << " (run inside tools/netns)";
    const JointArray pose = ctrl_->policy().artifact().default_pose;
    std::copy(pose.begin(), pose.end(), js_.q);
    imu_.quat[0] = 1.0f;
  }
  // One tick of the robot: its imu_t and joint_state_t (signed with a ring), then the runtime's answer.
  bool tick() {
    ++k_;
    imu_.utime = js_.utime = k_ * 2000;
    imu_.seq = js_.seq = k_;
    if (ring_) {
      peer_.publish_signed_by(*ring_, 0, t1::CH_IMU, imu_);
      peer_.publish_signed_by(*ring_, 0, t1::CH_JOINT_STATE, js_);
    } else {
      peer_.publish(t1::CH_IMU, imu_);
      peer_.publish(t1::CH_JOINT_STATE, js_);
    }
    const bool ticked = ctrl_->step_lockstep(500);
    peer_.drain();
    return ticked;
  }
  void ticks(int n) {
    for (int i = 0; i < n; ++i) ASSERT_TRUE(tick()) << "tick " << k_;
  }
  // A forged imu_t: 70 degrees of pitch, numbered seq.
  static t1::imu_t forged_imu(int64_t seq) {
    t1::imu_t f{};
    f.seq = seq;
    f.quat[0] = std::cos(kForgedPitchRad / 2);
    f.quat[2] = std::sin(kForgedPitchRad / 2);
    return f;
  }
  bool ok_ = false;
  std::shared_ptr<const KeyRing> ring_;
  LcmPeer peer_;
  std::unique_ptr<Controller> ctrl_;
  t1::imu_t imu_{};
  t1::joint_state_t js_{};
  int64_t k_ = 0;
};
}  // namespace

TEST(StateAuth, TakesOnlyTheRobotsFramesAndCountsEveryRefusalByReason) {
  auto robot = test_ring("state_robot", {test_sender(1, 0x44)});
  auto other = test_ring("state_other", {test_sender(1, 0x55)});  // the same id, another key
  auto stranger = test_ring("state_stranger", {test_sender(9, 0x66)});
  Robot r("state_auth", robot);
  ASSERT_TRUE(r.ok_);
  r.ticks(100);
  ASSERT_EQ(r.ctrl_->supervisor().mode(), Mode::kPolicy) << r.ctrl_->supervisor().last_fault();
  const t1::imu_t forged = Robot::forged_imu(r.k_ + 1);
  r.peer_.publish(t1::CH_IMU, forged);                          // unsigned
  r.peer_.publish_signed_by(*other, 0, t1::CH_IMU, forged);     // wrong key
  r.peer_.publish_signed_by(*stranger, 0, t1::CH_IMU, forged);  // a sender the file does not list
  t1::imu_t stale = forged;
  stale.sender_id = 1, stale.timestamp_us = wall_us() - 5'000'000;
  const auto stale_bytes = robot->encode_signed(0, t1::CH_IMU, stale);  // the robot's key, 5 s old
  r.peer_.publish_raw(t1::CH_IMU, stale_bytes.data(), stale_bytes.size());
  t1::imu_t early = r.imu_;
  early.sender_id = 1, early.timestamp_us = wall_us();
  const auto captured = robot->encode_signed(0, t1::CH_IMU, early);
  r.peer_.publish_raw(t1::CH_IMU, captured.data(), captured.size());  // taken once...
  ASSERT_TRUE(r.tick());
  r.peer_.publish_raw(t1::CH_IMU, captured.data(), captured.size());  // ...and refused when replayed
  std::vector<uint8_t> odd = robot->encode_signed(0, t1::CH_IMU, early);
  odd[odd.size() - kTagBytes - 1] = 7;  // tag_size 7
  r.peer_.publish_raw(t1::CH_IMU, odd.data(), odd.size());
  r.ticks(kStatusTicks);
  const CommandAuth& a = r.ctrl_->state_auth();
  EXPECT_EQ(a.refused(Refusal::kUnsigned), 1);
  EXPECT_EQ(a.refused(Refusal::kBadTag), 1);
  EXPECT_EQ(a.refused(Refusal::kUnknownSender), 1);
  EXPECT_EQ(a.refused(Refusal::kStale), 1);
  EXPECT_EQ(a.refused(Refusal::kReplayed), 1);
  EXPECT_EQ(a.refused(Refusal::kTagSize), 1);
  EXPECT_EQ(r.ctrl_->supervisor().mode(), Mode::kPolicy) << r.ctrl_->supervisor().last_fault();
  EXPECT_EQ(r.ctrl_->transport().imu.msg.quat[0], 1.0f) << "a refused frame reached the loop";
  const t1::controller_status_t& s = r.ctrl_->status();
  EXPECT_EQ(s.state_auth, "signed (robot key, 1 senders)");
  EXPECT_EQ(s.state_refused_bad_tag, 1);
  EXPECT_EQ(s.state_refused_stale, 1);
  // The warning is live: set in the status period the refusals came in, gone in a quiet one.
  r.peer_.publish_signed_by(*other, 0, t1::CH_JOINT_STATE, r.js_);
  const int64_t sent_at = r.ctrl_->ticks();
  while (r.ctrl_->status().ticks <= sent_at) ASSERT_TRUE(r.tick());  // the first status after it
  EXPECT_TRUE(r.ctrl_->status().fault_bits & fault_bit::kStateRefused);
  EXPECT_TRUE(says(r.ctrl_->status().state_source, "REFUSING STATE")) << r.ctrl_->status().state_source;
  EXPECT_TRUE(says(r.ctrl_->status().state_source, "T1_JOINT_STATE")) << r.ctrl_->status().state_source;
  r.ticks(2 * kStatusTicks);
  EXPECT_FALSE(r.ctrl_->status().fault_bits & fault_bit::kStateRefused) << r.ctrl_->status().state_source;
}

TEST(StateAuth, WithoutARobotKeyStateIsUnauthenticatedAndSaysSo) {
  Robot r("state_unauth", nullptr);
  ASSERT_TRUE(r.ok_);
  r.ticks(kStatusTicks);
  EXPECT_EQ(r.ctrl_->status().state_auth, "unauthenticated (no --robot-key)");
  EXPECT_EQ(r.ctrl_->supervisor().mode(), Mode::kPolicy) << r.ctrl_->supervisor().last_fault();
}

// Rule R12 over LCM, no robot key: a replayed stream numbered from 1 beside the robot's is a FAULT naming it,
// and the robot's frames stay the ones the loop reads.
TEST(SecondStateSource, AReplayBesideTheRobotIsAFaultNamedForItAndNeverAdopted) {
  Robot r("second_replay", nullptr);
  ASSERT_TRUE(r.ok_);
  r.ticks(200);
  ASSERT_EQ(r.ctrl_->supervisor().mode(), Mode::kPolicy);
  for (int64_t seq = 1; seq <= 20; ++seq) {
    r.peer_.publish(t1::CH_IMU, Robot::forged_imu(seq));
    ASSERT_TRUE(r.tick());
  }
  EXPECT_EQ(r.ctrl_->supervisor().mode(), Mode::kFault);
  EXPECT_TRUE(says(r.ctrl_->supervisor().last_fault(), "second state source on T1_IMU"))
      << r.ctrl_->supervisor().last_fault();
  EXPECT_TRUE(r.ctrl_->supervisor().fault_bits() & fault_bit::kSecondStateSource);
  EXPECT_EQ(r.ctrl_->supervisor().second_source_frames(), 20);
  EXPECT_EQ(r.ctrl_->transport().imu.msg.seq, r.k_) << "the robot's stream is the one followed";
  EXPECT_EQ(r.ctrl_->transport().imu.msg.quat[0], 1.0f);
}

TEST(SecondStateSource, AStreamFarAheadOfTheRobotsIsAFaultToo) {
  Robot r("second_ahead", nullptr);
  ASSERT_TRUE(r.ok_);
  r.ticks(200);
  r.peer_.publish(t1::CH_IMU, Robot::forged_imu(r.k_ + 100000));
  ASSERT_TRUE(r.tick());
  EXPECT_EQ(r.ctrl_->supervisor().mode(), Mode::kFault);
  EXPECT_TRUE(says(r.ctrl_->supervisor().last_fault(), "second state source on T1_IMU: seq"))
      << r.ctrl_->supervisor().last_fault();
  EXPECT_TRUE(says(r.ctrl_->supervisor().last_fault(), "far ahead")) << r.ctrl_->supervisor().last_fault();
  r.ticks(20);
  EXPECT_EQ(r.ctrl_->transport().imu.msg.seq, r.k_);
}

// The rule itself, on its own clock: a restart is taken once the old stream has been silent.
TEST(SecondStateSource, ARealRestartStopsTheOldStreamFirstAndIsTaken) {
  SafetyConfig cfg;
  Supervisor sup(cfg);
  double t = 100.0;
  for (int64_t seq = 5000; seq < 5100; ++seq, t += 0.002) ASSERT_TRUE(sup.accept_imu_seq(seq, t));
  t += cfg.restart_quiet_s;  // the robot's stack restarted: silent for the quiet time
  EXPECT_TRUE(sup.accept_imu_seq(0, t));
  EXPECT_TRUE(sup.accept_imu_seq(1, t + 0.002));
  EXPECT_EQ(sup.mode(), Mode::kPassive) << sup.last_fault();
  EXPECT_EQ(sup.second_source_frames(), 0);
  // Alive: the same numbering jump is a second source.
  EXPECT_FALSE(sup.accept_imu_seq(5000, t + 0.004));
  EXPECT_EQ(sup.mode(), Mode::kFault);
  EXPECT_TRUE(says(sup.last_fault(), "second state source on T1_IMU")) << sup.last_fault();
  // Late and duplicate frames within R3's window stay R3's: rejected, not a second source.
  Supervisor quiet(cfg);
  ASSERT_TRUE(quiet.accept_joint_seq(100, 1.0));
  EXPECT_FALSE(quiet.accept_joint_seq(99, 1.001));
  EXPECT_FALSE(quiet.accept_joint_seq(100, 1.001));
  EXPECT_EQ(quiet.second_source_frames(), 0);
  EXPECT_NE(quiet.mode(), Mode::kFault);
}
