// Chain mode (keyframe_chain.hpp): the keyframe getup's roll → rise → stand, switched and latched by the rules of
// common/events.keyframe_stage on the Trunk's height from T1_SIM_STATUS; its manifest; the controller over real
// LCM in lockstep (run inside tools/netns).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "lcm_peer.hpp"
#include "t1/sim_status_t.hpp"
#include "t1rt/controller.hpp"
#include "t1rt/keyframe_chain.hpp"
#include "test_artifact.hpp"

using namespace t1rt;
using namespace t1rt::testing;
namespace fs = std::filesystem;

namespace {
constexpr int64_t kTickUs = 2000;
constexpr float kLyingM = 0.2f, kKneelM = 0.4f, kStandM = 0.66f;
constexpr float kDegToRad = 0.017453292f;

// (w x y z) of a pitch about the world y axis: +90° points the Trunk's forward axis down (face down).
std::array<float, 4> pitched(float deg) {
  const float half = 0.5f * deg * kDegToRad;
  return {std::cos(half), 0.0f, std::sin(half), 0.0f};
}

TrunkReadings readings(float height_m, float pitch_deg, float spin_rad_s = 0.0f) {
  const auto q = pitched(pitch_deg);
  const float gyro[3] = {spin_rad_s, 0.0f, 0.0f};
  return trunk_readings(q.data(), gyro, height_m);
}

// A chain folder of three constant policies (one gain set), each driving the hip pitch its own way.
std::string write_chain(const std::string& name, const std::string& handover = "kneel_band") {
  const fs::path dir = fs::path(::testing::TempDir().empty() ? "/tmp" : ::testing::TempDir()) / ("t1rt_" + name);
  fs::create_directories(dir);
  const char* stages[3] = {"roll", "rise", "stand"};
  for (int i = 0; i < 3; ++i) {
    ArtifactSpec s = make_spec({8});
    s.meta["name"] = std::string(stages[i]) + "_test";
    for (auto& kv : s.tensors)
      if (kv.first.rfind("layers.", 0) == 0) std::fill(kv.second.data.begin(), kv.second.data.end(), 0.0f);
    s.tensors["layers.1.bias"].data[11] = -1.0f + static_cast<float>(i);
    fs::copy_file(write_spec(name + "_" + stages[i], s), dir / (std::string(stages[i]) + ".safetensors"),
                  fs::copy_options::overwrite_existing);
  }
  std::ofstream(dir / kChainManifest)
      << "{\"format\": \"t1-keyframe-chain/1\", \"stages\": {\"roll\": "
         "\"roll.safetensors\", \"rise\": \"rise.safetensors\", \"stand\": \"stand.safetensors\"}, \"handover\": \""
      << handover << "\"}";
  return dir.string();
}

void expect_refused(const std::string& dir, const std::string& json, const std::string& named) {
  std::ofstream(fs::path(dir) / kChainManifest) << json;
  try {
    read_chain_file(dir);
    ADD_FAILURE() << "accepted: " << json;
  } catch (const ArtifactError& e) {
    EXPECT_NE(std::string(e.what()).find(named), std::string::npos) << e.what();
  }
}
}  // namespace

TEST(KeyframeChainRule, FirstStageFromTheTrunkHeight) {
  EXPECT_EQ(next_stage(ChainStage::kStart, readings(kLyingM, -90.0f), t1::kKneelGateUpError), ChainStage::kRoll);
  EXPECT_EQ(next_stage(ChainStage::kStart, readings(kLyingM, 90.0f), t1::kKneelGateUpError), ChainStage::kRise)
      << "already face down and still: the rise";
  EXPECT_EQ(next_stage(ChainStage::kStart, readings(0.45f, 10.0f), t1::kKneelGateUpError), ChainStage::kRise);
  EXPECT_EQ(next_stage(ChainStage::kStart, readings(kStandM, 0.0f), t1::kKneelGateUpError), ChainStage::kStand);
}

TEST(KeyframeChainRule, RollHandsOverFaceDownAndStill) {
  EXPECT_EQ(next_stage(ChainStage::kRoll, readings(kLyingM, 90.0f), 0.01f), ChainStage::kRise);
  EXPECT_EQ(next_stage(ChainStage::kRoll, readings(kLyingM, 90.0f, 2.0f), 0.01f), ChainStage::kRoll) << "tumbling";
  EXPECT_EQ(next_stage(ChainStage::kRoll, readings(kLyingM, 45.0f), 0.01f), ChainStage::kRoll) << "on its side";
}

TEST(KeyframeChainRule, RiseHandsOverAtTheKneelWithinItsUprightBound) {
  // 2° off vertical: ‖u − e_z‖ ≈ 0.035, inside the band (0.05), outside §4.8's gate (0.01)
  EXPECT_EQ(next_stage(ChainStage::kRise, readings(kKneelM, 2.0f), t1::kKneelGateUpError), ChainStage::kRise);
  EXPECT_EQ(next_stage(ChainStage::kRise, readings(kKneelM, 2.0f), t1::kKneelBandUpError), ChainStage::kStand);
  EXPECT_EQ(next_stage(ChainStage::kRise, readings(kKneelM, 0.3f), t1::kKneelGateUpError), ChainStage::kStand);
  EXPECT_EQ(next_stage(ChainStage::kRise, readings(0.38f, 0.0f), t1::kKneelBandUpError), ChainStage::kRise)
      << "below the gate's height";
  EXPECT_EQ(next_stage(ChainStage::kRise, readings(kLyingM, -90.0f), 0.01f), ChainStage::kRoll)
      << "tipped onto its back";
  const float half = 0.5f * 90.0f * kDegToRad;
  const std::array<float, 4> on_side = {std::cos(half), std::sin(half), 0.0f, 0.0f};  // rolled 90° about x
  const float still[3] = {0.0f, 0.0f, 0.0f};
  EXPECT_EQ(next_stage(ChainStage::kRise, trunk_readings(on_side.data(), still, kLyingM), 0.01f), ChainStage::kRoll)
      << "tipped onto its side";
  EXPECT_EQ(next_stage(ChainStage::kRise, readings(kLyingM, 60.0f), 0.01f), ChainStage::kRise) << "face down";
}

TEST(KeyframeChainRule, StandLatchesUntilTheTrunkIsDown) {
  EXPECT_EQ(next_stage(ChainStage::kStand, readings(kKneelM, 20.0f), 0.01f), ChainStage::kStand);
  EXPECT_EQ(next_stage(ChainStage::kStand, readings(kLyingM, 0.0f), 0.01f), ChainStage::kRoll);
}

TEST(KeyframeChainFile, ReadsTheMembersAndTheHandOver) {
  const std::string dir = write_chain("chain_file");
  ASSERT_TRUE(is_chain_folder(dir));
  EXPECT_FALSE(is_chain_folder(dir + "/roll.safetensors"));
  const ChainFile chain = read_chain_file(dir);
  EXPECT_EQ(fs::path(chain.members[1]).filename(), "rise.safetensors");
  EXPECT_EQ(chain.handover, "kneel_band");
  EXPECT_FLOAT_EQ(chain.handover_up_error, t1::kKneelBandUpError);
}

TEST(KeyframeChainFile, RefusesWhatCannotRunNamingIt) {
  const std::string dir = write_chain("chain_refused");
  const std::string stages = "\"stages\": {\"roll\": \"roll.safetensors\", \"rise\": \"rise.safetensors\", ";
  expect_refused(dir, "[1, 2]", "not a JSON object");
  expect_refused(dir, "{\"format\": \"t1-keyframe-chain/0\"}", "format must be");
  expect_refused(dir, "{\"format\": \"t1-keyframe-chain/1\", \"stages\": {}}", "stages must name exactly");
  expect_refused(dir, "{\"format\": \"t1-keyframe-chain/1\", " + stages + "\"stand\": \"../x.safetensors\"}}",
                 "must be a file name");
  expect_refused(dir, "{\"format\": \"t1-keyframe-chain/1\", " + stages + "\"stand\": \"absent.safetensors\"}}",
                 "does not exist");
  expect_refused(dir,
                 "{\"format\": \"t1-keyframe-chain/1\", " + stages +
                     "\"stand\": \"stand.safetensors\"}, "
                     "\"handover\": \"kneel\"}",
                 "must be kneel_gate or kneel_band");
  expect_refused(dir, "{not json", "not a JSON object");
}

// The controller in chain mode: each tick's member follows the rule on the sim's Trunk height and the IMU.
TEST(KeyframeChainLcm, TheActingMemberFollowsTheRule) {
  LcmPeer peer;
  ASSERT_TRUE(peer.ok()) << "LCM peer could not start: run inside tools/netns";
  ControllerOptions opt;
  opt.policy_path = write_chain("chain_lcm");
  opt.lcm_url = resolve_lcm_url("");
  opt.clock = ClockMode::kLockstep;
  opt.quiet = true;
  opt.autostart = true;
  opt.safety.prepare_duration_s = 0.02;
  opt.auth = AuthMode::kUnauthenticated;
  const ChainFile file = read_chain_file(opt.policy_path);
  std::array<std::unique_ptr<PolicyEngine>, kChainStages> members;
  for (std::size_t i = 0; i < kChainStages; ++i)
    members[i] = std::make_unique<PolicyEngine>(load_artifact(file.members[i]));
  Controller ctrl(opt, std::move(members), file.handover_up_error);
  std::string error;
  ASSERT_TRUE(ctrl.open(&error)) << error;
  ASSERT_TRUE(ctrl.chain() && ctrl.switched());
  const JointArray pose = ctrl.active_policy().artifact().default_pose;
  int64_t k = 0;
  auto step = [&](float trunk_m, float pitch_deg) {
    ++k;
    t1::sim_status_t st{};
    st.utime = k * kTickUs;
    st.trunk_height = trunk_m;
    st.waist_height = trunk_m - 0.1f;
    peer.publish(t1::CH_SIM_STATUS, st);
    t1::imu_t imu{};
    imu.utime = k * kTickUs;
    imu.seq = k;
    const auto q = pitched(pitch_deg);
    std::copy(q.begin(), q.end(), imu.quat);
    peer.publish(t1::CH_IMU, imu);
    t1::joint_state_t js{};
    js.utime = k * kTickUs;
    js.seq = k;
    for (std::size_t i = 0; i < kJoints; ++i) js.q[i] = pose[i] + static_cast<float>(k % 2) * 1e-4f;
    peer.publish(t1::CH_JOINT_STATE, js);
    ASSERT_TRUE(ctrl.step_lockstep(500));
  };
  auto hold = [&](float trunk_m, float pitch_deg, int policy_ticks) {
    for (int i = 0; i < policy_ticks * 10; ++i) step(trunk_m, pitch_deg);
  };
  for (int i = 0; i < 60 && ctrl.supervisor().mode() != Mode::kPolicy; ++i) step(kLyingM, -90.0f);
  ASSERT_EQ(ctrl.supervisor().mode(), Mode::kPolicy) << ctrl.supervisor().last_fault();
  hold(kLyingM, -90.0f, 2);
  EXPECT_EQ(ctrl.chain_stage(), ChainStage::kRoll);
  EXPECT_EQ(ctrl.active_policy().artifact().name, "roll_test");
  hold(kLyingM, 90.0f, 2);
  EXPECT_EQ(ctrl.chain_stage(), ChainStage::kRise);
  hold(kKneelM, 2.0f, 2);  // inside the band this chain hands over at
  EXPECT_EQ(ctrl.chain_stage(), ChainStage::kStand);
  EXPECT_EQ(ctrl.active_policy().artifact().name, "stand_test");
  hold(0.45f, 15.0f, 2);  // latched: a stand that leans is still the stand
  EXPECT_EQ(ctrl.chain_stage(), ChainStage::kStand);
  hold(kLyingM, 0.0f, 2);
  EXPECT_EQ(ctrl.chain_stage(), ChainStage::kRoll);
  EXPECT_EQ(ctrl.supervisor().mode(), Mode::kPolicy) << ctrl.supervisor().last_fault();
}
