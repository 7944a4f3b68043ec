// Test helper: writes policy artifacts (safetensors: u64 LE header length, JSON header, raw f32 bytes) so
// tests can build valid and deliberately broken files without the Python exporter.
#pragma once
#include <cstdint>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "t1_contract.hpp"
#include "t1rt/artifact.hpp"

namespace t1rt::testing {

struct Tensor {
  std::vector<int64_t> shape;
  std::vector<float> data;
};

struct ArtifactSpec {
  nlohmann::json meta;                    // values are JSON (serialised to strings on write)
  std::map<std::string, Tensor> tensors;  // sorted by name, as the content hash needs
  bool fix_hash = true;                   // recompute content_hash from the tensors on write
};

inline std::vector<std::vector<float>> home_pose_and_gains() {
  // Menagerie home pose [rad] and moderate gains within the firmware limits.
  std::vector<float> pose = {0, 0, 0,    -1.4f, 0, -0.4f, 0, 1.4f, 0,    0.4f,  0, -0.2f,
                             0, 0, 0.4f, -0.2f, 0, -0.2f, 0, 0,    0.4f, -0.2f, 0};
  std::vector<float> kp(kJoints, 40.0f), kd(kJoints, 2.0f);
  return {pose, kp, kd};
}

// A random MLP artifact with the full observation (82) and the given hidden sizes.
inline ArtifactSpec make_spec(std::vector<int> hidden = {32, 32}, const std::string& rule = "tanh_normal",
                              const std::string& activation = "swish", unsigned seed = 7) {
  ArtifactSpec s;
  const auto pg = home_pose_and_gains();
  nlohmann::json joints = nlohmann::json::array();
  for (const char* n : t1::kJointNames) joints.push_back(n);
  s.meta = {{"schema_version", 1},
            {"name", "test_policy"},
            {"activation", activation},
            {"output_rule", rule},
            {"obs_terms",
             nlohmann::json::array({nlohmann::json::array({"gyro", 3}), nlohmann::json::array({"gravity", 3}),
                                    nlohmann::json::array({"command", 3}), nlohmann::json::array({"joint_pos", 23}),
                                    nlohmann::json::array({"joint_vel", 23}),
                                    nlohmann::json::array({"last_action", 23}), nlohmann::json::array({"phase", 4})})},
            {"joint_names", joints},
            {"default_pose", pg[0]},
            {"action_scale", 0.5},
            {"kp", pg[1]},
            {"kd", pg[2]},
            {"control_dt", 0.02},
            {"gait_frequency", 1.5},
            {"phase_freeze_command_norm", 0.1},
            {"command_ranges", {{"vx", {-1, 1}}, {"vy", {-0.8, 0.8}}, {"yaw_rate", {-1, 1}}}},
            {"trained", false},
            {"provenance", {{"git_commit", "test"}, {"steps", 0}, {"date", "today"}, {"command", "gtest"}}}};
  std::mt19937 rng(seed);
  std::normal_distribution<float> normal(0.0f, 0.3f);
  int in = 82;  // 3+3+3+23+23+23+4
  std::vector<int> outs = hidden;
  outs.push_back(rule == "tanh_normal" ? 46 : 23);
  for (std::size_t i = 0; i < outs.size(); ++i) {
    Tensor w{{outs[i], in}, {}}, b{{outs[i]}, {}};
    for (int k = 0; k < outs[i] * in; ++k) w.data.push_back(normal(rng) / std::sqrt(float(in)) * 3.0f);
    for (int k = 0; k < outs[i]; ++k) b.data.push_back(normal(rng) * 0.1f);
    s.tensors["layers." + std::to_string(i) + ".weight"] = w;
    s.tensors["layers." + std::to_string(i) + ".bias"] = b;
    in = outs[i];
  }
  Tensor mean{{82}, std::vector<float>(82, 0.0f)}, std{{82}, std::vector<float>(82, 1.0f)};
  for (int k = 0; k < 82; ++k) mean.data[k] = normal(rng) * 0.1f, std.data[k] = 0.5f + std::fabs(normal(rng));
  s.tensors["obs_mean"] = mean;
  s.tensors["obs_std"] = std;
  return s;
}

inline std::string raw_bytes(const Tensor& t) {
  return std::string(reinterpret_cast<const char*>(t.data.data()), t.data.size() * sizeof(float));
}

// Serialises the spec; `header_override` (if not empty) replaces the JSON header text.
inline std::string serialise(ArtifactSpec s, const std::string& header_override = "") {
  std::string data;
  nlohmann::json header = nlohmann::json::object();
  for (const auto& kv : s.tensors) {
    const std::string bytes = raw_bytes(kv.second);
    header[kv.first] = {
        {"dtype", "F32"}, {"shape", kv.second.shape}, {"data_offsets", {data.size(), data.size() + bytes.size()}}};
    data += bytes;
  }
  if (s.fix_hash) s.meta["content_hash"] = sha256_hex(data);
  nlohmann::json meta = nlohmann::json::object();
  for (auto it = s.meta.begin(); it != s.meta.end(); ++it) meta[it.key()] = it->dump();
  header["__metadata__"] = meta;
  const std::string text = header_override.empty() ? header.dump() : header_override;
  std::string out(8, '\0');
  const uint64_t n = text.size();
  for (int i = 0; i < 8; ++i) out[i] = static_cast<char>((n >> (8 * i)) & 0xFF);
  return out + text + data;
}

inline std::string write_file(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

inline std::string temp_path(const std::string& name) {
  return (::testing::TempDir().empty() ? std::string("/tmp/") : ::testing::TempDir()) + "t1rt_" + name + ".safetensors";
}

inline std::string write_spec(const std::string& name, const ArtifactSpec& s) {
  return write_file(temp_path(name), serialise(s));
}

}  // namespace t1rt::testing
