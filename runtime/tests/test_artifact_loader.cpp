// Every malformed artifact is rejected with a message naming the problem: by the loader, by the CLI at
// start-up (exit code 3, message on stderr). Hot-reload rejection is covered in test_supervisor_lcm.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>

#include "test_artifact.hpp"

using namespace t1rt;
using namespace t1rt::testing;

struct Malformed {
  const char* name;
  std::function<std::string()> bytes;
  const char* expected;  // substring of the error message (the field)
};

std::vector<Malformed> malformed_cases() {
  auto with = [](std::function<void(ArtifactSpec&)> edit) {
    return [edit] {
      ArtifactSpec s = make_spec();
      edit(s);
      return serialise(s);
    };
  };
  return {
      {"truncated",
       [] {
         const std::string b = serialise(make_spec());
         return b.substr(0, b.size() - 100);
       },
       "outside the"},
      {"shorter_than_header", [] { return std::string("\x05\x00", 2); }, "header_length"},
      {"huge_header_length",
       [] {
         std::string b = serialise(make_spec());
         for (int i = 0; i < 8; ++i) b[i] = '\xff';
         return b;
       },
       "header_length"},
      {"bad_header_json", [] { return serialise(make_spec(), "{not json!"); }, "'header'"},
      {"missing_tensor", with([](ArtifactSpec& s) { s.tensors.erase("obs_std"); }), "obs_std"},
      {"missing_bias", with([](ArtifactSpec& s) { s.tensors.erase("layers.1.bias"); }), "layers.1.bias"},
      {"wrong_shape_chain", with([](ArtifactSpec& s) {
         auto& w = s.tensors["layers.1.weight"];
         w.shape = {32, 16};
         w.data.resize(32 * 16);
       }),
       "layers.1.weight"},
      {"obs_size_ne_terms", with([](ArtifactSpec& s) { s.meta["obs_terms"].erase(6); }), "layers.0.weight"},
      {"unknown_term", with([](ArtifactSpec& s) { s.meta["obs_terms"][0][0] = "linvel"; }), "unknown term 'linvel'"},
      {"wrong_joint_order",
       with([](ArtifactSpec& s) { std::swap(s.meta["joint_names"][11], s.meta["joint_names"][12]); }), "joint_names"},
      {"wrong_joint_count", with([](ArtifactSpec& s) { s.meta["joint_names"].erase(22); }), "joint_names"},
      {"nan_weight", with([](ArtifactSpec& s) { s.tensors["layers.0.weight"].data[5] = NAN; }), "layers.0.weight"},
      {"zero_std", with([](ArtifactSpec& s) { s.tensors["obs_std"].data[3] = 0.0f; }), "obs_std"},
      {"wrong_dt", with([](ArtifactSpec& s) { s.meta["control_dt"] = 0.01; }), "control_dt"},
      {"kp_over_limit", with([](ArtifactSpec& s) { s.meta["kp"][14] = 900.0; }), "'kp'"},
      {"kd_negative", with([](ArtifactSpec& s) { s.meta["kd"][0] = -1.0; }), "'kd'"},
      {"unknown_activation", with([](ArtifactSpec& s) { s.meta["activation"] = "gelu"; }), "activation"},
      {"unknown_output_rule", with([](ArtifactSpec& s) { s.meta["output_rule"] = "softmax"; }), "output_rule"},
      {"output_width", with([](ArtifactSpec& s) { s.meta["output_rule"] = "linear"; }), "output rule needs 23"},
      {"hash_mismatch", with([](ArtifactSpec& s) {
         s.fix_hash = false;
         s.meta["content_hash"] = std::string(64, '0');
       }),
       "content_hash"},
      {"missing_metadata_key", with([](ArtifactSpec& s) { s.meta.erase("gait_frequency"); }), "gait_frequency"},
      {"schema_version", with([](ArtifactSpec& s) { s.meta["schema_version"] = 2; }), "schema_version"},
      {"nan_default_pose", with([](ArtifactSpec& s) { s.meta["default_pose"][2] = "nan"; }), "default_pose[2]"},
      {"bad_command_ranges", with([](ArtifactSpec& s) {
         s.meta["command_ranges"]["vx"] = {1, -1};
       }),
       "command_ranges.vx"},
      {"trained_not_bool", with([](ArtifactSpec& s) { s.meta["trained"] = "yes"; }), "trained"},
      // Every manifest number is checked for sign and range, and a removed tensor entry whose
      // bytes stay in the file is named as the missing tensor.
      {"missing_tensor_bytes_kept",
       [] {
         const ArtifactSpec s = make_spec();
         const std::string full = serialise(s);
         uint64_t n = 0;
         for (int i = 0; i < 8; ++i) n |= static_cast<uint64_t>(static_cast<unsigned char>(full[i])) << (8 * i);
         nlohmann::json header = nlohmann::json::parse(full.substr(8, n));
         header.erase("obs_std");
         return serialise(s, header.dump());
       },
       "'obs_std': missing tensor"},
      {"action_scale_huge", with([](ArtifactSpec& s) { s.meta["action_scale"] = 1e6; }), "action_scale[0]"},
      {"action_scale_negative", with([](ArtifactSpec& s) { s.meta["action_scale"] = -0.5; }), "action_scale[0]"},
      {"action_scale_zero_joint", with([](ArtifactSpec& s) {
         std::vector<float> v(kJoints, 0.5f);
         v[7] = 0.0f;
         s.meta["action_scale"] = v;
       }),
       "action_scale[7]"},
      {"default_pose_10_rad",
       with([](ArtifactSpec& s) { s.meta["default_pose"] = std::vector<float>(kJoints, 10.0f); }), "default_pose[0]"},
      {"default_pose_one_joint_out", with([](ArtifactSpec& s) { s.meta["default_pose"][14] = -0.5; }),
       "default_pose[14]"},
      {"gait_frequency_huge", with([](ArtifactSpec& s) { s.meta["gait_frequency"] = 1e4; }), "gait_frequency"},
      {"command_range_huge", with([](ArtifactSpec& s) {
         s.meta["command_ranges"]["vy"] = {-1e9, 1e9};
       }),
       "command_ranges.vy"},
  };
}

TEST(ArtifactLoader, AcceptsValidArtifact) {
  const std::string path = write_spec("valid", make_spec());
  const PolicyArtifact a = load_artifact(path);
  EXPECT_EQ(a.obs_size, 82);
  EXPECT_EQ(a.layers.size(), 3u);
  EXPECT_EQ(a.output_rule, OutputRule::kTanhNormal);
  EXPECT_FLOAT_EQ(a.action_scale[4], 0.5f);
  EXPECT_EQ(a.content_hash.size(), 64u);
  EXPECT_FALSE(a.trained);
}

TEST(ArtifactLoader, RejectsEveryMalformedArtifactNamingTheField) {
  const auto cases = malformed_cases();
  ASSERT_GE(cases.size(), 10u);
  for (const Malformed& c : cases) {
    const std::string path = write_file(temp_path(c.name), c.bytes());
    try {
      load_artifact(path);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const ArtifactError& e) {
      EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos)
          << c.name << ": message '" << e.what() << "' does not name '" << c.expected << "'";
    }
  }
}

TEST(ArtifactLoader, MissingFileNamesThePath) {
  EXPECT_THROW(load_artifact("/nonexistent/p.safetensors"), ArtifactError);
}

// Start-up: the CLI exits 3 and names the problem on stderr for every malformed artifact.
TEST(RuntimeCli, BadArtifactExitsThreeWithMessage) {
  for (const Malformed& c : malformed_cases()) {
    const std::string path = write_file(temp_path(std::string("cli_") + c.name), c.bytes());
    const std::string err = temp_path(std::string("cli_") + c.name) + ".stderr";
    const std::string cmd = std::string(T1_RUNTIME_BIN) + " --policy " + path + " --quiet --duration 0.1 2> " + err;
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status)) << c.name;
    EXPECT_EQ(WEXITSTATUS(status), 3) << c.name;
    std::ifstream in(err);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find(c.expected), std::string::npos) << c.name << ": stderr '" << text << "'";
  }
}

TEST(RuntimeCli, UsageAndHelpExitCodes) {
  const std::string bin = T1_RUNTIME_BIN;
  EXPECT_EQ(WEXITSTATUS(std::system((bin + " --help > /dev/null").c_str())), 0);
  EXPECT_EQ(WEXITSTATUS(std::system((bin + " 2> /dev/null").c_str())), 2);  // --policy missing
  EXPECT_EQ(WEXITSTATUS(std::system((bin + " --policy x --clock fast 2> /dev/null").c_str())), 2);
  EXPECT_EQ(WEXITSTATUS(std::system((bin + " --policy x --bogus 2> /dev/null").c_str())), 2);
}

// Numbers that would run forever, exit at once with 0, or pin to a garbage core.
// The policy path is bogus on purpose: argument errors must be found first (exit 2, not 3).
TEST(RuntimeCli, NonsenseNumbersAreUsageErrors) {
  const std::string bin = T1_RUNTIME_BIN;
  for (const char* args : {"--duration nan", "--duration inf", "--duration 1e30", "--duration -1", "--duration 0",
                           "--duration 5s", "--rt-cpu abc", "--rt-cpu 1x", "--rt-cpu -2", "--rt-cpu 99999999999"}) {
    const std::string err = temp_path("cli_numbers") + ".stderr";
    const int status = std::system((bin + " --policy x " + args + " 2> " + err).c_str());
    ASSERT_TRUE(WIFEXITED(status)) << args;
    EXPECT_EQ(WEXITSTATUS(status), 2) << args;
    std::ifstream in(err);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string option = std::string(args).substr(0, std::string(args).find(' '));
    EXPECT_NE(text.find(option), std::string::npos) << args << ": stderr '" << text << "'";
  }
}
