// Rules R8 (silent motor), R9 (frozen encoder) and R10 (impossible reading) of src/safety_supervisor.cpp on
// the Supervisor alone: N cycles, random loss that must never trip, the frozen-encoder torque threshold,
// time and motion evidence, the range and speed bounds, and the warning that blocks PREPARE in DAMPING/PASSIVE. The out-of-process checks against the simulator are in
// tests/test_motor_watchdog.py.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>

#include "t1_motor_protocol.h"
#include "t1rt/safety.hpp"

using namespace t1rt;

namespace {
constexpr int kKnee = 14, kAnkle = 15;  // Left_Knee_Pitch (limit 60 N·m), Left_Ankle_Pitch

constexpr float kTurning = 0.5f;    // [rad/s] a body rate walking keeps (the walk's filtered rate is 0.23-0.86)
constexpr float kLimbSpeed = 0.5f;  // [rad/s] the motors' mean speed walking (filtered 0.36-1.1)

class Robot {
 public:
  Robot() : sup_(config()) {
    for (std::size_t i = 0; i < kJoints; ++i) {
      artifact_.default_pose[i] = 0.5f * (T1_MOTORS[i].q_min_rad + T1_MOTORS[i].q_max_rad);  // inside R6's range
      artifact_.kp[i] = 150.0f;
      artifact_.kd[i] = 2.0f;
      q_[i] = artifact_.default_pose[i];
    }
  }
  static SafetyConfig config() {
    SafetyConfig c;
    c.prepare_duration_s = 0.01;
    return c;
  }
  void tick() {
    ++k_;
    const double now = 0.002 * static_cast<double>(k_);
    StateView s;
    s.now_s = s.imu_time_s = s.joint_time_s = now;
    s.have_imu = s.have_joint = true;
    s.joint_seq = k_ + seq_offset_;
    s.quat = quat_;
    s.gyro = gyro_;
    s.q = q_;
    s.dq = dq_;
    s.motor_status = status_;
    sup_.begin_tick(s, artifact_);
    sup_.finish_tick(s, artifact_, artifact_.default_pose, out_);
  }
  void ticks(int n) {
    for (int i = 0; i < n; ++i) tick();
  }
  // The robot in motion as R9 needs it: the IMU says the body turns, the other motors say the limbs move
  // (their readings are not integrated from dq here: R9 reads dq only as evidence).
  void in_motion(bool on, int except = -1) {
    gyro_[1] = on ? kTurning : 0.0f;
    for (std::size_t i = 0; i < kJoints; ++i) dq_[i] = on && static_cast<int>(i) != except ? kLimbSpeed : 0.0f;
  }
  // Moves joint i to q [rad] at 5 rad/s, a tick a step (a jump would be R10's impossible reading).
  void move_to(int i, float q) {
    constexpr float kStepRad = 0.01f;
    while (std::fabs(q - q_[i]) > kStepRad) {
      q_[i] += q > q_[i] ? kStepRad : -kStepRad;
      tick();
    }
    q_[i] = q;
    tick();
  }
  void to_policy() {
    sup_.set_autostart(true);
    for (int i = 0; i < 100 && sup_.mode() != Mode::kPolicy; ++i) tick();
    ASSERT_EQ(sup_.mode(), Mode::kPolicy) << sup_.last_info();
  }
  Supervisor sup_;
  PolicyArtifact artifact_;
  float q_[kJoints]{}, dq_[kJoints]{}, quat_[4]{1, 0, 0, 0}, gyro_[3]{};
  int32_t status_[kJoints]{};
  t1::joint_command_t out_{};
  int64_t k_ = 0, seq_offset_ = 0;
};

bool says(const char* text, const char* what) { return std::string(text).find(what) != std::string::npos; }

// In DAMPING with a motor warning, a request for PREPARE is refused with a reason saying `what`.
void expect_prepare_refused(Robot& r, const char* what) {
  ASSERT_EQ(r.sup_.mode(), Mode::kDamping);
  EXPECT_TRUE(r.sup_.fault_bits() & fault_bit::kMotorWarning);
  r.sup_.request_mode(Mode::kPrepare);
  r.tick();
  EXPECT_EQ(r.sup_.mode(), Mode::kDamping);
  EXPECT_TRUE(says(r.sup_.last_info(), what)) << r.sup_.last_info();
}

// The supervisor is in FAULT by `bit`, its reason saying `what`.
void expect_fault(const Robot& r, int32_t bit, const char* what) {
  ASSERT_EQ(r.sup_.mode(), Mode::kFault);
  EXPECT_TRUE(r.sup_.fault_bits() & bit);
  EXPECT_TRUE(says(r.sup_.last_fault(), what)) << r.sup_.last_fault();
}
}  // namespace

TEST(SilentMotor, FaultsOnMoreThanTheAllowedConsecutiveMissedRepliesNamingTheMotor) {
  Robot r;
  r.to_policy();
  r.status_[kAnkle] = T1_STATUS_NO_REPLY;
  r.ticks(kMotorSilentMaxCycles);
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.tick();
  expect_fault(r, fault_bit::kMotorSilent, "motor 15 (Left_Ankle_Pitch) silent");
  for (std::size_t i = 0; i < kJoints; ++i) EXPECT_EQ(r.out_.kp[i], 0.0f);  // latched damping
}

TEST(SilentMotor, AReplyRestartsTheCount) {
  Robot r;
  r.to_policy();
  for (int round = 0; round < 50; ++round) {
    r.status_[kAnkle] = T1_STATUS_NO_REPLY;
    r.ticks(kMotorSilentMaxCycles);
    r.status_[kAnkle] = 0;
    r.tick();
  }
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
}

TEST(SilentMotor, FivePercentRandomFrameLossNeverTrips) {
  // 5 % loss of every reply, independently per motor and cycle, for 400 s at 500 Hz: the longest run of
  // missed replies stays far below the limit (odds of a run of 11: 0.05^11 per motor-cycle).
  Robot r;
  r.to_policy();
  std::mt19937 rng(48);
  std::bernoulli_distribution lost(0.05);
  int run[kJoints]{}, longest = 0;
  for (int k = 0; k < 200000 && r.sup_.mode() == Mode::kPolicy; ++k) {
    for (std::size_t i = 0; i < kJoints; ++i) {
      r.status_[i] = lost(rng) ? static_cast<int32_t>(T1_STATUS_NO_REPLY) : 0;
      run[i] = r.status_[i] ? run[i] + 1 : 0;
      longest = std::max(longest, run[i]);
    }
    r.tick();
  }
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  EXPECT_LT(longest, kMotorSilentMaxCycles / 2) << "the limit has the margin the rule comment claims";
}

TEST(SilentMotor, InDampingAndPassiveItIsAWarningThatBlocksPrepare) {
  Robot r;
  r.tick();
  r.status_[kAnkle] = T1_STATUS_NO_REPLY;
  r.ticks(kMotorSilentMaxCycles + 1);
  EXPECT_EQ(r.sup_.mode(), Mode::kPassive);
  EXPECT_TRUE(r.sup_.fault_bits() & fault_bit::kMotorWarning);
  r.sup_.request_mode(Mode::kDamping);
  r.tick();
  expect_prepare_refused(r, "prepare refused: motor 15 (Left_Ankle_Pitch) silent");
  r.status_[kAnkle] = 0;  // the motor answers again: PREPARE is allowed
  r.sup_.request_mode(Mode::kPrepare);
  r.tick();
  EXPECT_EQ(r.sup_.mode(), Mode::kPrepare) << r.sup_.last_info();
  EXPECT_FALSE(r.sup_.fault_bits() & fault_bit::kMotorWarning);
}

TEST(FrozenEncoder, BitIdenticalUnderTorqueAboveTheThresholdWhileTheBodyTurnsFaultsAfterTheTimeNamingTheMotor) {
  Robot r;
  r.in_motion(true, kKnee);
  r.ticks(200);  // the motion filters have settled (4 time constants)
  r.to_policy();
  r.move_to(kKnee, r.q_[kKnee] + 0.35f);  // target 0.35 rad away at kp 150: |PD torque| 52.5 N·m > the knee's threshold
  ASSERT_GT(0.35f * 150.0f, frozen_encoder_torque_nm(60.0f));
  r.ticks(kFrozenEncoderMaxCycles);
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.tick();
  expect_fault(r, fault_bit::kEncoderFrozen, "motor 14 (Left_Knee_Pitch) encoder frozen");
}

TEST(FrozenEncoder, AStillEncoderUnderStandingLoadsOrAMovingOneUnderFullTorqueNeverTrips) {
  Robot r;
  r.in_motion(true, kKnee);
  r.to_policy();
  const float below = 0.95f * frozen_encoder_torque_nm(60.0f) / 150.0f;
  r.move_to(kKnee, r.q_[kKnee] + below);  // just below the threshold, for 10 s: a robot standing or lying still
  r.ticks(5000);
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  const float q = r.artifact_.default_pose[kKnee] + 0.35f;  // 52.5 N·m, but the encoder moves a float step each tick
  r.move_to(kKnee, q);
  for (int k = 0; k < 5000; ++k) {
    r.q_[kKnee] = k % 2 ? std::nextafter(q, 1.0f) : q;
    r.tick();
  }
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
}

TEST(FrozenEncoder, TheThresholdIsAFractionOfTheLimitWithAFloor) {
  EXPECT_FLOAT_EQ(frozen_encoder_torque_nm(60.0f), 60.0f * kFrozenEncoderTorqueFraction);  // knee
  EXPECT_FLOAT_EQ(frozen_encoder_torque_nm(7.0f),
                  kFrozenEncoderMinTorqueNm);  // head: above its 7 N·m limit, never reached
}

TEST(FrozenEncoder, MissedRepliesAreNoReadingAndAQuietTickRestartsTheClock) {
  Robot r;
  r.in_motion(true, kKnee);
  r.to_policy();
  const float pose = r.artifact_.default_pose[kKnee];
  r.move_to(kKnee, pose + 0.35f);
  const int half = kFrozenEncoderMaxCycles / 2;
  for (int round = 0; round < 20; ++round) {
    r.ticks(half);
    r.move_to(kKnee, pose);  // torque ~0 on the way: not loaded
    r.move_to(kKnee, pose + 0.35f);
  }
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.status_[kKnee] = T1_STATUS_NO_REPLY;  // a dead motor's q repeats too: R8 names it, not R9
  r.ticks(kMotorSilentMaxCycles + 1);
  ASSERT_EQ(r.sup_.mode(), Mode::kFault);
  EXPECT_TRUE(says(r.sup_.last_fault(), "silent")) << r.sup_.last_fault();
}

TEST(FrozenEncoder, AStillBodyIsNoEvidenceHoweverLoadedAndLongItHolds) {
  // A robot standing, kneeling or on a test stand: every encoder may repeat under load. An IMU at rest (with a
  // gyro bias well below the motion threshold) says nothing moves, so nothing contradicts the still reading.
  Robot r;
  r.gyro_[0] = 0.3f * kBodyMotionMinRateRadS;
  r.to_policy();
  r.move_to(kKnee, r.q_[kKnee] + 0.35f);  // 52.5 N·m held for 60 s
  r.move_to(kAnkle, r.q_[kAnkle] + 0.1f);  // 15 N·m > 13 N·m: the ankle that carried the standing getup expert's weight
  r.ticks(30000);
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
}

TEST(FrozenEncoder, AJointHeldAtItsStopIsExplainedByTheStopEvenWhileTheBodyTurns) {
  Robot r;
  r.in_motion(true, kKnee);
  r.to_policy();
  r.artifact_.default_pose[kKnee] = T1_MOTORS[kKnee].q_min_rad + 0.3f;  // the target pulls 0.3 rad off the stop
  r.move_to(kKnee, T1_MOTORS[kKnee].q_min_rad - 0.01f);  // pressed a little past it by the load: 46.5 N·m, still
  r.ticks(5000);
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
}

TEST(FrozenEncoder, TheRobotMustMoveThroughoutTheStillReading) {
  Robot r;
  r.in_motion(true, kKnee);
  r.ticks(200);
  r.to_policy();
  r.move_to(kKnee, r.q_[kKnee] + 0.35f);
  r.in_motion(false);  // the robot comes to rest: its filtered motion falls below the thresholds (in 40 states
  r.ticks(200);        // from 0.5 rad/s), and the count restarts
  r.in_motion(true, kKnee);
  r.ticks(kFrozenEncoderMaxCycles / 2);
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.ticks(kFrozenEncoderMaxCycles);
  EXPECT_EQ(r.sup_.mode(), Mode::kFault);
}

TEST(FrozenEncoder, ABodyTurningWithItsLimbsStillIsNotEnough) {
  // A robot swaying after a push: the trunk turns slowly, the limbs hold still, a loaded joint keeps its code.
  Robot r;
  r.gyro_[1] = kTurning;
  r.to_policy();
  r.move_to(kKnee, r.q_[kKnee] + 0.35f);
  r.ticks(5000);
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
}

TEST(ImpossibleReading, BeyondTheRangeByMoreThanTheSoftStopFaultsAtOnceNamingTheMotor) {
  Robot r;
  r.to_policy();
  const float q_max = T1_MOTORS[kKnee].q_max_rad;
  r.move_to(kKnee, q_max);
  for (float past = 0.0f; past < kImpossibleRangeMarginRad; past += 0.005f) {  // pressed past the stop: fine
    r.q_[kKnee] = q_max + past;
    r.tick();
  }
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.q_[kKnee] = q_max + kImpossibleRangeMarginRad + 0.006f;
  r.tick();
  expect_fault(r, fault_bit::kImpossibleReading, "motor 14 (Left_Knee_Pitch) impossible reading: q 2.846 rad");
}

TEST(ImpossibleReading, AStepFasterThanTheReplyCanSayFaultsUnlessRepliesWereMissedOrThePublisherRestarted) {
  Robot r;
  r.to_policy();
  const float v_max = kImpossibleSpeedFactor * T1_CLASS_RANGES[T1_MOTORS[kKnee].motor_class].v_max_rads;
  const float step = 0.9f * v_max * 0.002f;
  for (int k = 0; k < 20; ++k) {  // nearly as fast as the rule allows, up and down
    r.q_[kKnee] += k % 2 ? -step : step;
    r.tick();
  }
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.status_[kKnee] = T1_STATUS_NO_REPLY;  // two replies missed: three cycles for the next step
  r.ticks(2);
  r.status_[kKnee] = 0;
  r.q_[kKnee] += 2.5f * step;
  r.tick();
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.seq_offset_ = -r.k_;  // the publisher restarts its numbering: the next reply has nothing before it
  r.q_[kKnee] -= 0.3f;
  r.tick();
  EXPECT_EQ(r.sup_.mode(), Mode::kPolicy) << r.sup_.last_fault();
  r.q_[kKnee] += 1.2f * step;  // beyond the bound in one cycle
  r.tick();
  ASSERT_EQ(r.sup_.mode(), Mode::kFault);
  EXPECT_TRUE(says(r.sup_.last_fault(), "motor 14 (Left_Knee_Pitch) impossible reading")) << r.sup_.last_fault();
  EXPECT_TRUE(says(r.sup_.last_fault(), "in 2 ms")) << r.sup_.last_fault();
}

TEST(ImpossibleReading, InDampingItIsAWarningThatBlocksPrepare) {
  Robot r;
  r.tick();
  r.sup_.request_mode(Mode::kDamping);
  r.q_[kAnkle] = 3.0f;  // the outside test client's every-joint-at-3-rad pose
  r.tick();
  expect_prepare_refused(r, "prepare refused: motor 15 (Left_Ankle_Pitch) impossible reading");
}
