// The DDS transport's pure parts (no network): gravity from the Booster IMU's roll/pitch/yaw, the
// LowState_ checks that keep a malformed sample out of the live state, and the LowCmd_ the robot gets.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "t1_contract.hpp"
#include "t1_motor_protocol.h"
#include "t1rt/dds_transport.hpp"
#include "t1rt/policy.hpp"
#include "t1rt/robot_link.hpp"

using namespace t1rt;

namespace {
constexpr float kTol = 1e-5f;
using MotorState = booster_interface_msg_dds__MotorState_;

struct Sample {
  std::vector<MotorState> motors;
  DdsLowState msg{};
  explicit Sample(std::size_t n) : motors(n) {
    for (std::size_t i = 0; i < n; ++i) {
      motors[i].q = 0.01f * static_cast<float>(i);
      motors[i].dq = -0.02f * static_cast<float>(i);
      motors[i].tau_est = 0.5f;
    }
    msg.imu_state.rpy[0] = 0.1f;
    msg.imu_state.rpy[1] = -0.2f;
    msg.imu_state.rpy[2] = 1.0f;
    msg.imu_state.acc[2] = 9.81f;
    msg.motor_state_serial._buffer = motors.data();
    msg.motor_state_serial._length = msg.motor_state_serial._maximum = static_cast<uint32_t>(n);
  }
};
}  // namespace

TEST(GravityFromRpy, LevelPitchedAndRolled) {
  float g[3];
  const float level[3] = {0, 0, 2.0f};  // any yaw: gravity straight down the IMU's -z
  gravity_from_rpy(level, g);
  EXPECT_NEAR(g[0], 0, kTol);
  EXPECT_NEAR(g[1], 0, kTol);
  EXPECT_NEAR(g[2], -1, kTol);
  const float nose_down[3] = {0, static_cast<float>(M_PI / 2), 0};  // +pitch: nose (x) down
  gravity_from_rpy(nose_down, g);
  EXPECT_NEAR(g[0], 1, kTol);
  EXPECT_NEAR(g[1], 0, kTol);
  EXPECT_NEAR(g[2], 0, kTol);
  const float left_up[3] = {static_cast<float>(M_PI / 2), 0, 0};  // +roll: left side (y) up
  gravity_from_rpy(left_up, g);
  EXPECT_NEAR(g[0], 0, kTol);
  EXPECT_NEAR(g[1], -1, kTol);
  EXPECT_NEAR(g[2], 0, kTol);
}

TEST(GravityFromRpy, AgreesWithTheQuaternionPathTheObservationUses) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> angle(-3.0f, 3.0f), half(-1.5f, 1.5f);
  for (int k = 0; k < 200; ++k) {
    const float rpy[3] = {angle(rng), half(rng), angle(rng)};
    float quat[4], from_quat[3], closed[3];
    quat_from_rpy(rpy, quat);
    EXPECT_NEAR(quat[0] * quat[0] + quat[1] * quat[1] + quat[2] * quat[2] + quat[3] * quat[3], 1.0f, kTol);
    projected_gravity(quat, from_quat);
    gravity_from_rpy(rpy, closed);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(from_quat[i], closed[i], kTol) << "rpy " << rpy[0] << " " << rpy[1];
  }
}

TEST(GravityFromRpy, YawIsAboutZThenPitchThenRoll) {
  // R = Rz(yaw) Ry(pitch) Rx(roll): yaw alone is a rotation about world z by yaw.
  const float yaw_only[3] = {0, 0, 0.8f};
  float q[4];
  quat_from_rpy(yaw_only, q);
  EXPECT_NEAR(q[0], std::cos(0.4f), kTol);
  EXPECT_NEAR(q[3], std::sin(0.4f), kTol);
  EXPECT_NEAR(q[1], 0, kTol);
  EXPECT_NEAR(q[2], 0, kTol);
}

TEST(LowStateCheck, AcceptsAWellFormedSampleAndConvertsIt) {
  Sample s(kJoints);
  ASSERT_EQ(check_low_state(s.msg), nullptr);
  t1::imu_t imu{};
  t1::joint_state_t joint{};
  low_state_to_messages(s.msg, &imu, &joint);
  float g_msg[3], g_rpy[3];
  projected_gravity(imu.quat, g_msg);
  gravity_from_rpy(s.msg.imu_state.rpy, g_rpy);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(g_msg[i], g_rpy[i], kTol);
  EXPECT_NEAR(imu.accel[2], 9.81f, kTol);
  EXPECT_NEAR(joint.q[22], 0.22f, kTol);
  EXPECT_NEAR(joint.dq[3], -0.06f, kTol);
}

TEST(LowStateCheck, AChangedLostCounterIsANoReplyForThatMotorOnly) {
  Sample s(kJoints);
  t1::imu_t imu{};
  t1::joint_state_t joint{};
  uint32_t prev[kJoints] = {};
  s.motors[15].lost = 1;
  low_state_to_messages(s.msg, &imu, &joint);  // first sample: nothing to compare with
  for (std::size_t i = 0; i < kJoints; ++i) EXPECT_EQ(joint.motor_status[i], 0) << i;
  low_state_to_messages(s.msg, &imu, &joint, prev);
  for (std::size_t i = 0; i < kJoints; ++i)
    EXPECT_EQ(joint.motor_status[i], i == 15 ? int32_t(T1_STATUS_NO_REPLY) : 0) << i;
  prev[15] = 1;
  low_state_to_messages(s.msg, &imu, &joint, prev);
  EXPECT_EQ(joint.motor_status[15], 0);
}

TEST(LowStateCheck, RejectsWrongLengthsAndNonFiniteValuesNamingTheProblem) {
  for (std::size_t n : {std::size_t{0}, kJoints - 1, kJoints + 1, std::size_t{200}}) {
    Sample s(n);
    const char* why = check_low_state(s.msg);
    ASSERT_NE(why, nullptr) << n << " motors";
    EXPECT_NE(std::string(why).find(n > kJoints ? "more than 23" : "fewer than 23"), std::string::npos) << why;
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Sample bad_q(kJoints);
  bad_q.motors[11].q = nan;
  EXPECT_NE(std::string(check_low_state(bad_q.msg)).find("non-finite motor"), std::string::npos);
  Sample bad_imu(kJoints);
  bad_imu.msg.imu_state.gyro[1] = std::numeric_limits<float>::infinity();
  EXPECT_NE(std::string(check_low_state(bad_imu.msg)).find("non-finite IMU"), std::string::npos);
}

TEST(LowCmd, SerialWithTheContractsCustomModeFieldsAndTheSupervisorsNumbers) {
  t1::joint_command_t cmd{};
  for (std::size_t i = 0; i < kJoints; ++i) {
    cmd.q_des[i] = 0.1f * static_cast<float>(i);
    cmd.kp[i] = 50.0f;
    cmd.kd[i] = 2.0f;
    cmd.tau_ff[i] = -1.0f;
  }
  std::array<DdsMotorCmd, kJoints> motors{};
  DdsLowCmd out{};
  joint_command_to_low_cmd(cmd, &out, motors.data());
  EXPECT_EQ(static_cast<int>(out.cmd_type), t1::kDdsCmdTypeSerial);
  EXPECT_EQ(static_cast<int>(out.cmd_type), static_cast<int>(booster_interface_msg_dds__SERIAL));
  ASSERT_EQ(out.motor_cmd._length, kJoints);
  EXPECT_FALSE(out.motor_cmd._release);
  EXPECT_NEAR(out.motor_cmd._buffer[7].q, 0.7f, kTol);
  EXPECT_NEAR(out.motor_cmd._buffer[7].kp, 50.0f, kTol);
  EXPECT_NEAR(out.motor_cmd._buffer[7].tau, -1.0f, kTol);
  EXPECT_EQ(out.motor_cmd._buffer[7].mode, t1::kDdsMotorMode);
  EXPECT_NEAR(out.motor_cmd._buffer[7].weight, t1::kDdsMotorWeight, kTol);
}

// The controller sees one RobotLink: the LCM link opens over the LCM transport without a network of its own,
// and leaves refusals to the transport's verifier and rules R3 / R12 (nothing refused at the link).
TEST(RobotLink, LcmLinkRefusesNothingItselfAndEachKindIsNamed) {
  LcmTransport lcm;
  std::string error;
  std::unique_ptr<RobotLink> link =
      open_robot_link(RobotLinkKind::kLcm, 0, ClockMode::kLockstep, nullptr, &lcm, &error);
  ASSERT_NE(link, nullptr) << error;
  EXPECT_EQ(link->rejected_samples(), 0);
  EXPECT_STREQ(link->last_rejection(), "");
  EXPECT_EQ(link->second_writer_samples(), 0);
  EXPECT_STREQ(link->second_writer(), "");
  EXPECT_TRUE(state_on_lcm(RobotLinkKind::kLcm));
  EXPECT_FALSE(state_on_lcm(RobotLinkKind::kDds));
  EXPECT_STREQ(robot_link_description(RobotLinkKind::kLcm), "LCM");
  EXPECT_NE(std::string(robot_link_description(RobotLinkKind::kDds)).find("rt/low_state"), std::string::npos);
}
