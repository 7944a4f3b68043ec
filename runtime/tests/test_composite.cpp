// Composite mode (composite.hpp): a getup + upright pair switched by the privileged waist height from
// T1_SIM_STATUS, over real LCM in lockstep (run inside tools/netns), plus the pair checks and the CLI.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "lcm_peer.hpp"
#include "t1/sim_status_t.hpp"
#include "t1rt/composite.hpp"
#include "t1rt/controller.hpp"
#include "test_artifact.hpp"
#include "test_keys.hpp"

using namespace t1rt;
using namespace t1rt::testing;

namespace {
constexpr int64_t kTickUs = 2000;
constexpr int kTicksPerPolicyTick = 10;  // 20 ms control period / 2 ms loop tick
constexpr int kHipPitch = 11;
constexpr int kGetupObsSize = 3 + 3 + 23 + 23 + 23;  // gyro gravity joint_pos joint_vel last_action
constexpr float kUprightActionScaleRad = 0.5f;       // [rad per unit action]: make_spec's
constexpr float kGetupActionScaleRad = 0.8f;         // a wider map (the ankle rolls allow ≤ 0.88)

// A constant policy: zero weights, the last bias drives one joint to default + 0.5 * tanh(bias) [rad].
ArtifactSpec constant_spec(const std::string& name, float hip_bias, bool getup_terms) {
  ArtifactSpec s = make_spec({8});
  s.meta["name"] = name;
  if (getup_terms) s.meta["action_scale"] = kGetupActionScaleRad;
  for (auto& kv : s.tensors)
    if (kv.first.rfind("layers.", 0) == 0) std::fill(kv.second.data.begin(), kv.second.data.end(), 0.0f);
  s.tensors["layers.1.bias"].data[kHipPitch] = hip_bias;
  if (getup_terms) {  // the getup expert's observation subset: no command, no phase
    s.meta["obs_terms"] =
        nlohmann::json::array({nlohmann::json::array({"gyro", 3}), nlohmann::json::array({"gravity", 3}),
                               nlohmann::json::array({"joint_pos", 23}), nlohmann::json::array({"joint_vel", 23}),
                               nlohmann::json::array({"last_action", 23})});
    Tensor& w0 = s.tensors["layers.0.weight"];
    w0.shape = {8, kGetupObsSize};
    w0.data.assign(8 * kGetupObsSize, 0.0f);
    s.tensors["obs_mean"] = Tensor{{kGetupObsSize}, std::vector<float>(kGetupObsSize, 0.0f)};
    s.tensors["obs_std"] = Tensor{{kGetupObsSize}, std::vector<float>(kGetupObsSize, 1.0f)};
  }
  return s;
}

class CompositeLcm : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(peer_.ok()) << "LCM peer could not start: run inside tools/netns";
    ControllerOptions opt;
    opt.policy_path = write_spec("composite_getup", constant_spec("getup_test", 2.0f, true));
    opt.upright_policy_path = write_spec("composite_upright", constant_spec("upright_test", -2.0f, false));
    opt.lcm_url = resolve_lcm_url("");
    opt.clock = ClockMode::kLockstep;
    opt.quiet = true;
    opt.autostart = true;
    opt.safety.prepare_duration_s = 0.02;
    opt.auth = AuthMode::kSigned;  // the operator's signed commands
    opt.keys = test_ring("composite", {test_sender(1, 0x22)});
    peer_.sign_with(opt.keys);
    ctrl_ = std::make_unique<Controller>(opt, std::make_unique<PolicyEngine>(load_artifact(opt.policy_path)),
                                         std::make_unique<PolicyEngine>(load_artifact(opt.upright_policy_path)));
    std::string error;
    ASSERT_TRUE(ctrl_->open(&error)) << error;
    pose_ = ctrl_->active_policy().artifact().default_pose;
  }
  // One lockstep exchange at sim time k*2 ms; sim status (waist height) sent first unless send_sim is false.
  const t1::joint_command_t& step(float waist_m, bool send_sim = true) {
    ++k_;
    const int64_t now = k_ * kTickUs;
    if (send_sim) {
      t1::sim_status_t st{};
      st.utime = now;
      st.waist_height = waist_m;
      st.scenario = "flat";
      peer_.publish(t1::CH_SIM_STATUS, st);
    }
    t1::imu_t imu{};
    imu.utime = now;
    imu.seq = k_;
    imu.quat[0] = 1.0f;
    peer_.publish(t1::CH_IMU, imu);
    t1::joint_state_t js{};
    js.utime = now;
    js.seq = k_;
    // The encoders move a count each tick: still ones under the getup member's torque would be a frozen
    // encoder (rule R9 of src/safety_supervisor.cpp).
    for (std::size_t i = 0; i < kJoints; ++i) js.q[i] = pose_[i] + static_cast<float>(k_ % 2) * 1e-4f;
    peer_.publish(t1::CH_JOINT_STATE, js);
    EXPECT_TRUE(ctrl_->step_lockstep(500));
    EXPECT_TRUE(peer_.wait_command(js.seq));
    return peer_.last_cmd;
  }
  void to_policy(float waist_m) {
    for (int i = 0; i < 40 && ctrl_->supervisor().mode() != Mode::kPolicy; ++i) step(waist_m);
    ASSERT_EQ(ctrl_->supervisor().mode(), Mode::kPolicy) << ctrl_->supervisor().last_fault();
  }

  LcmPeer peer_;
  std::unique_ptr<Controller> ctrl_;
  JointArray pose_{};
  int64_t k_ = 0;
};
}  // namespace

TEST(CompositePair, SelectsGetupStrictlyBelowHalfAMetre) {
  EXPECT_EQ(select_member(0.2f), CompositeMember::kGetup);
  EXPECT_EQ(select_member(0.4999f), CompositeMember::kGetup);
  EXPECT_EQ(select_member(0.5f), CompositeMember::kUpright);
  EXPECT_EQ(select_member(0.6f), CompositeMember::kUpright);
}

TEST(CompositePair, DifferentGainsRejectedNamingTheJoint) {
  const PolicyArtifact getup = load_artifact(write_spec("pair_g", constant_spec("g", 1.0f, true)));
  ArtifactSpec other = constant_spec("u", 1.0f, false);
  other.meta["kd"][3] = 2.5;
  const PolicyArtifact upright = load_artifact(write_spec("pair_u", other));
  try {
    check_composite_pair(getup, upright);
    FAIL() << "gain mismatch accepted";
  } catch (const ArtifactError& e) {
    EXPECT_EQ(e.field(), "kd");
    EXPECT_NE(std::string(e.what()).find(t1::kJointNames[3]), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(check_composite_pair(getup, load_artifact(write_spec("pair_u2", constant_spec("u", 1.0f, false)))));
}

TEST(CompositePair, CliRejectsMismatchedPairWithExitThree) {
  ArtifactSpec other = constant_spec("u", 1.0f, false);
  other.meta["kp"][0] = 41.0;
  const std::string g = write_spec("cli_g", constant_spec("g", 1.0f, true));
  const std::string u = write_spec("cli_u", other);
  const std::string err = temp_path("cli_pair_err") + ".txt";
  const std::string cmd =
      std::string(T1_RUNTIME_BIN) + " --policy " + g + " --policy-upright " + u + " --quiet --duration 0.1 2> " + err;
  const int rc = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(rc));
  EXPECT_EQ(WEXITSTATUS(rc), 3);
  std::stringstream text;
  text << std::ifstream(err).rdbuf();
  EXPECT_NE(text.str().find("'kp'"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("one gain set"), std::string::npos) << text.str();
}

TEST_F(CompositeLcm, WaitsForSimStatusBeforeLeavingPassive) {
  for (int i = 0; i < 20; ++i) step(0.6f, /*send_sim=*/false);
  EXPECT_EQ(ctrl_->supervisor().mode(), Mode::kPassive);
  to_policy(0.6f);
}

TEST_F(CompositeLcm, SwitchesMemberByWaistHeightAndSaysSo) {
  to_policy(0.3f);
  for (int i = 0; i < 60; ++i) step(0.3f);
  EXPECT_EQ(ctrl_->member(), CompositeMember::kGetup);
  EXPECT_EQ(ctrl_->active_policy().artifact().name, "getup_test");
  // getup drives the hip pitch above its default pose, upright below (after the 0.05 rad/tick rate limit)
  EXPECT_GT(peer_.last_cmd.q_des[kHipPitch], pose_[kHipPitch] + 0.3f);
  peer_.drain();
  ASSERT_GT(peer_.statuses, 0);
  EXPECT_NE(peer_.last_status.policy_name.find("composite[getup=getup_test,upright=upright_test] active=getup"),
            std::string::npos)
      << peer_.last_status.policy_name;
  EXPECT_NE(peer_.last_status.info.find("T1_SIM_STATUS"), std::string::npos) << peer_.last_status.info;

  for (int i = 0; i < 60; ++i) step(0.62f);
  EXPECT_EQ(ctrl_->member(), CompositeMember::kUpright);
  EXPECT_LT(peer_.last_cmd.q_des[kHipPitch], pose_[kHipPitch] - 0.3f);
  EXPECT_EQ(ctrl_->member_switches(), 2);  // upright (initial) -> getup -> upright
}

TEST_F(CompositeLcm, IdleMemberReadsTheAppliedTargetsInItsOwnMap) {
  to_policy(0.3f);
  for (int i = 0; i < kTicksPerPolicyTick; ++i) step(0.3f);
  ASSERT_EQ(ctrl_->member(), CompositeMember::kGetup);
  PolicyEngine& getup = ctrl_->policy();
  for (int i = 0; i < kTicksPerPolicyTick; ++i) step(0.62f);
  ASSERT_EQ(ctrl_->member(), CompositeMember::kUpright);
  PolicyEngine& upright = ctrl_->active_policy();
  // the upright member drove: target = pose + 0.5 * tanh(-2) [rad]; the getup member reads that target in
  // its own, wider map, not the upright's action
  const float applied_rad = upright.q_target()[kHipPitch] - pose_[kHipPitch];
  EXPECT_NEAR(getup.action()[kHipPitch], applied_rad / kGetupActionScaleRad, 1e-6f);
  EXPECT_NEAR(getup.action()[kHipPitch], upright.action()[kHipPitch] * kUprightActionScaleRad / kGetupActionScaleRad,
              1e-6f);
  for (int i = 0; i < kTicksPerPolicyTick; ++i) step(0.3f);
  ASSERT_EQ(ctrl_->member(), CompositeMember::kGetup);
  // the getup member drove to pose + 0.8 tanh(2) = pose + 0.77 rad: past the upright's ±0.5 rad reach, so
  // the upright member reads its previous action as the end of its range
  EXPECT_FLOAT_EQ(upright.action()[kHipPitch], 1.0f);
}

TEST_F(CompositeLcm, StaleSimStatusHoldsThenFaults) {
  to_policy(0.6f);
  for (int i = 0; i < 5; ++i) step(0.6f, false);  // 10 ms without sim status: still fresh (age <= 10 ms)
  EXPECT_EQ(ctrl_->supervisor().fault_bits() & fault_bit::kSimStatusHold, 0);
  step(0.6f, false);  // 12 ms: hold
  EXPECT_NE(ctrl_->supervisor().fault_bits() & fault_bit::kSimStatusHold, 0);
  EXPECT_EQ(ctrl_->supervisor().mode(), Mode::kPolicy);
  for (int i = 0; i < 20; ++i) step(0.6f, false);  // > 50 ms: FAULT
  EXPECT_EQ(ctrl_->supervisor().mode(), Mode::kFault);
  EXPECT_NE(ctrl_->supervisor().fault_bits() & fault_bit::kSimStatusStale, 0);
  EXPECT_NE(std::string(ctrl_->supervisor().last_fault()).find("sim_status_t stale"), std::string::npos);
}

TEST_F(CompositeLcm, NonFiniteWaistHeightFaults) {
  to_policy(0.6f);
  step(std::nanf(""));
  EXPECT_EQ(ctrl_->supervisor().mode(), Mode::kFault);
  EXPECT_NE(ctrl_->supervisor().fault_bits() & fault_bit::kNonFiniteSimStatus, 0);
}

// A sim_status_t whose first string claims length 0 (no NUL: lcm-gen's decoder throws on it) is a decode
// error and changes nothing.
TEST_F(CompositeLcm, SimStatusWithAnImpossibleStringLengthIsADecodeError) {
  to_policy(0.6f);
  t1::sim_status_t st{};
  std::vector<uint8_t> buf(static_cast<std::size_t>(st.getEncodedSize()));
  st.encode(buf.data(), 0, static_cast<int>(buf.size()));
  const std::size_t scenario_length_at = 3 * sizeof(int64_t) + sizeof(float);  // fingerprint, utime, step, rtf
  std::fill(buf.begin() + scenario_length_at, buf.begin() + scenario_length_at + sizeof(int32_t), 0);
  const int64_t before = ctrl_->transport().decode_errors;
  peer_.publish_raw(t1::CH_SIM_STATUS, buf.data(), buf.size());
  step(0.6f);
  EXPECT_EQ(ctrl_->transport().decode_errors, before + 1);
  EXPECT_EQ(ctrl_->supervisor().mode(), Mode::kPolicy) << ctrl_->supervisor().last_fault();
}

TEST_F(CompositeLcm, HotReloadRejected) {
  to_policy(0.6f);
  write_spec("composite_reload", constant_spec("other", 0.0f, false));
  peer_.command("load_policy", "t1rt_composite_reload.safetensors");
  for (int i = 0; i < 200 && ctrl_->reload_message().empty(); ++i) step(0.6f);
  EXPECT_NE(ctrl_->reload_message().find("not supported in composite mode"), std::string::npos)
      << ctrl_->reload_message();
  EXPECT_EQ(ctrl_->active_policy().artifact().name, "upright_test");
}

TEST(CompositeOff, SinglePolicyNeverListensToSimStatus) {
  LcmPeer peer;
  ASSERT_TRUE(peer.ok());
  ControllerOptions opt;
  opt.policy_path = write_spec("single", constant_spec("single", 0.0f, false));
  opt.lcm_url = resolve_lcm_url("");
  opt.clock = ClockMode::kLockstep;
  opt.quiet = true;
  Controller ctrl(opt, std::make_unique<PolicyEngine>(load_artifact(opt.policy_path)));
  std::string error;
  ASSERT_TRUE(ctrl.open(&error)) << error;
  t1::sim_status_t st{};
  st.utime = kTickUs;
  peer.publish(t1::CH_SIM_STATUS, st);
  t1::joint_state_t js{};
  js.utime = kTickUs;
  peer.publish(t1::CH_JOINT_STATE, js);
  ASSERT_TRUE(ctrl.step_lockstep(500));
  EXPECT_EQ(ctrl.transport().sim_status.received, 0);
  EXPECT_FALSE(ctrl.composite());
}

TEST(RuntimeCli, PrepareSecondsValidated) {
  const std::string g = write_spec("cli_prep", constant_spec("p", 0.0f, false));
  for (const char* bad : {"0", "-1", "11", "abc"}) {
    const std::string cmd =
        std::string(T1_RUNTIME_BIN) + " --policy " + g + " --prepare-s " + bad + " --quiet 2>/dev/null";
    const int rc = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(rc));
    EXPECT_EQ(WEXITSTATUS(rc), 2) << "--prepare-s " << bad;
  }
}
