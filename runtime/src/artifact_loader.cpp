// Loader and validator of policy artifacts (policies/ARTIFACT.md). Every field is checked; a failure is an
// ArtifactError naming the field, so a bad file never reaches the control loop.
#include <openssl/sha.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "t1_contract.hpp"
#include "t1_motor_protocol.h"
#include "t1rt/artifact.hpp"

namespace t1rt {

static_assert(kJoints == t1::kNumJoints, "runtime joint count != messages/contract.json");
static_assert(kJoints == T1_NUM_MOTORS, "runtime joint count != firmware motor table");

namespace {
using nlohmann::json;
constexpr std::size_t kHeaderLengthBytes = 8;               // safetensors: u64 little-endian header size
constexpr uint64_t kMaxHeaderBytes = 100u * 1024u * 1024u;  // safetensors' own limit (100 MB)

struct TensorView {
  std::vector<int64_t> shape;
  std::string bytes;
};

[[noreturn]] void fail(const std::string& field, const std::string& problem) { throw ArtifactError(field, problem); }

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    fail("file", "'" + path + "' is a folder, not an artifact file (*.safetensors)");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("file", "cannot open '" + path + "'");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

json parse_meta_value(const std::map<std::string, std::string>& meta, const std::string& key) {
  auto it = meta.find(key);
  if (it == meta.end()) fail(key, "missing from __metadata__");
  json value = json::parse(it->second, nullptr, false);
  if (value.is_discarded()) fail(key, "value is not valid JSON text: '" + it->second + "'");
  return value;
}

double finite_number(const json& v, const std::string& field) {
  if (!v.is_number()) fail(field, "expected a number, got " + v.dump());
  const double x = v.get<double>();
  if (!std::isfinite(x)) fail(field, "not finite");
  return x;
}

JointArray joint_floats(const json& v, const std::string& field) {
  if (!v.is_array() || v.size() != kJoints) fail(field, "expected a list of " + std::to_string(kJoints) + " numbers");
  JointArray out{};
  for (std::size_t i = 0; i < kJoints; ++i)
    out[i] = static_cast<float>(finite_number(v[i], field + "[" + std::to_string(i) + "]"));
  return out;
}

std::string joint_field(const std::string& field, std::size_t i) {
  return field + "[" + std::to_string(i) + "] (" + t1::kJointNames[i] + ")";
}

// default_pose must lie inside the joint's range (firmware motor table); a pose outside it is a target
// the supervisor would clamp on every tick, i.e. a broken file.
void check_default_pose(const JointArray& pose) {
  for (std::size_t i = 0; i < kJoints; ++i)
    if (pose[i] < T1_MOTORS[i].q_min_rad || pose[i] > T1_MOTORS[i].q_max_rad)
      fail(joint_field("default_pose", i), std::to_string(pose[i]) + " rad outside the joint range [" +
                                               std::to_string(T1_MOTORS[i].q_min_rad) + ", " +
                                               std::to_string(T1_MOTORS[i].q_max_rad) + "] rad");
}

// action_scale: strictly positive (a negative scale mirrors the policy), at most kMaxActionScaleRad and at
// most the joint's full range (one unit of action may not sweep more than the whole joint).
void check_action_scale(const JointArray& scale) {
  for (std::size_t i = 0; i < kJoints; ++i) {
    const double range = T1_MOTORS[i].q_max_rad - T1_MOTORS[i].q_min_rad;
    const double max = std::min(kMaxActionScaleRad, range);
    if (!(scale[i] > 0.0f) || scale[i] > max)
      fail(joint_field("action_scale", i), std::to_string(scale[i]) + " rad per unit outside (0, " +
                                               std::to_string(max) + "] (documented maximum " +
                                               std::to_string(kMaxActionScaleRad) + ", joint range)");
  }
}

void check_gains(const JointArray& gains, float max, const std::string& field) {
  for (std::size_t i = 0; i < kJoints; ++i)
    if (gains[i] < 0.0f || gains[i] > max)
      fail(field, "joint " + std::string(t1::kJointNames[i]) + " gain " + std::to_string(gains[i]) + " outside [0, " +
                      std::to_string(max) + "] (firmware limit)");
}

// *unreferenced: data bytes no tensor entry covers; reported after the named tensors are checked, so a
// missing tensor is named as such and not as a data-size mismatch.
std::map<std::string, TensorView> parse_safetensors(const std::string& file, std::map<std::string, std::string>& meta,
                                                    std::size_t* unreferenced) {
  if (file.size() < kHeaderLengthBytes) fail("header_length", "file shorter than the 8-byte header length (truncated)");
  uint64_t header_len = 0;
  for (std::size_t i = 0; i < kHeaderLengthBytes; ++i)
    header_len |= static_cast<uint64_t>(static_cast<unsigned char>(file[i])) << (8 * i);
  if (header_len > kMaxHeaderBytes || header_len > file.size() - kHeaderLengthBytes)
    fail("header_length", std::to_string(header_len) + " bytes, but the file has only " +
                              std::to_string(file.size() - kHeaderLengthBytes) + " after it (truncated or corrupt)");
  const json header = json::parse(file.substr(kHeaderLengthBytes, header_len), nullptr, false);
  if (header.is_discarded() || !header.is_object()) fail("header", "not a JSON object");
  const std::size_t data_start = kHeaderLengthBytes + header_len;
  const std::size_t data_size = file.size() - data_start;
  std::map<std::string, TensorView> tensors;
  std::size_t covered = 0;
  for (auto it = header.begin(); it != header.end(); ++it) {
    if (it.key() == "__metadata__") {
      if (!it->is_object()) fail("__metadata__", "not an object");
      for (auto m = it->begin(); m != it->end(); ++m) {
        if (!m->is_string()) fail(m.key(), "__metadata__ values must be strings (JSON text)");
        meta[m.key()] = m->get<std::string>();
      }
      continue;
    }
    const json& t = *it;
    const std::string& name = it.key();
    if (!t.is_object() || !t.contains("dtype") || !t.contains("shape") || !t.contains("data_offsets"))
      fail(name, "tensor entry needs dtype, shape and data_offsets");
    if (t["dtype"] != "F32") fail(name, "dtype " + t["dtype"].dump() + ", expected \"F32\"");
    TensorView view;
    int64_t count = 1;
    for (const json& d : t["shape"]) {
      if (!d.is_number_integer() || d.get<int64_t>() < 0) fail(name, "bad shape " + t["shape"].dump());
      view.shape.push_back(d.get<int64_t>());
      count *= view.shape.back();
    }
    const json& off = t["data_offsets"];
    if (!off.is_array() || off.size() != 2 || !off[0].is_number_unsigned() || !off[1].is_number_unsigned())
      fail(name, "data_offsets must be [begin, end]");
    const uint64_t begin = off[0].get<uint64_t>(), end = off[1].get<uint64_t>();
    if (begin > end || end > data_size)
      fail(name, "data_offsets [" + std::to_string(begin) + ", " + std::to_string(end) + ") outside the " +
                     std::to_string(data_size) + "-byte data section (truncated?)");
    if (end - begin != static_cast<uint64_t>(count) * sizeof(float))
      fail(name, "byte size " + std::to_string(end - begin) + " does not match shape " + t["shape"].dump());
    view.bytes = file.substr(data_start + begin, end - begin);
    covered += end - begin;
    tensors.emplace(name, std::move(view));
  }
  *unreferenced = covered <= data_size ? data_size - covered : 0;
  if (covered > data_size)
    fail("data", "tensor byte ranges overlap: they cover " + std::to_string(covered) + " of " +
                     std::to_string(data_size) + " data bytes");
  return tensors;
}

const TensorView& tensor(const std::map<std::string, TensorView>& tensors, const std::string& name) {
  auto it = tensors.find(name);
  if (it == tensors.end()) fail(name, "missing tensor");
  return it->second;
}

Eigen::VectorXf finite_vector(const TensorView& t, const std::string& name, int64_t size) {
  if (t.shape.size() != 1 || t.shape[0] != size) fail(name, "shape must be (" + std::to_string(size) + ",)");
  Eigen::VectorXf v(size);
  std::memcpy(v.data(), t.bytes.data(), t.bytes.size());
  if (!v.allFinite()) fail(name, "contains NaN or Inf");
  return v;
}
}  // namespace

int obs_term_size(const std::string& name) {
  static const std::map<std::string, int> kSizes = {{"gyro", 3},
                                                    {"gravity", 3},
                                                    {"command", 3},
                                                    {"joint_pos", static_cast<int>(kJoints)},
                                                    {"joint_vel", static_cast<int>(kJoints)},
                                                    {"last_action", static_cast<int>(kJoints)},
                                                    {"phase", 4}};
  auto it = kSizes.find(name);
  return it == kSizes.end() ? -1 : it->second;
}

std::string sha256_hex(const std::string& bytes) {
  unsigned char digest[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), digest);
  static const char* kHex = "0123456789abcdef";
  std::string out;
  for (unsigned char c : digest) {
    out += kHex[c >> 4];
    out += kHex[c & 0xF];
  }
  return out;
}

PolicyArtifact load_artifact(const std::string& path) { return parse_artifact(path, read_file(path)); }

PolicyArtifact parse_artifact(const std::string& path, const std::string& file) {
  PolicyArtifact a;
  a.path = path;
  std::map<std::string, std::string> meta;
  std::size_t unreferenced_bytes = 0;
  const auto tensors = parse_safetensors(file, meta, &unreferenced_bytes);

  const json version = parse_meta_value(meta, "schema_version");
  if (!version.is_number_integer() || version.get<int>() != kSchemaVersion)
    fail("schema_version", version.dump() + ", this runtime reads " + std::to_string(kSchemaVersion));
  a.schema_version = kSchemaVersion;
  const json name = parse_meta_value(meta, "name");
  if (!name.is_string() || name.get<std::string>().empty()) fail("name", "expected a non-empty string");
  a.name = name.get<std::string>();

  const json act = parse_meta_value(meta, "activation");
  const std::map<std::string, Activation> kActs = {{"swish", Activation::kSwish},
                                                   {"elu", Activation::kElu},
                                                   {"tanh", Activation::kTanh},
                                                   {"relu", Activation::kRelu}};
  if (!act.is_string() || !kActs.count(act.get<std::string>()))
    fail("activation", act.dump() + " is not swish/elu/tanh/relu");
  a.activation = kActs.at(act.get<std::string>());
  const json rule = parse_meta_value(meta, "output_rule");
  if (rule == "tanh_normal") a.output_rule = OutputRule::kTanhNormal;
  else if (rule == "linear") a.output_rule = OutputRule::kLinear;
  else fail("output_rule", rule.dump() + " is not tanh_normal/linear");

  const json terms = parse_meta_value(meta, "obs_terms");
  if (!terms.is_array() || terms.empty()) fail("obs_terms", "expected a non-empty list of [name, size]");
  for (const json& t : terms) {
    if (!t.is_array() || t.size() != 2 || !t[0].is_string() || !t[1].is_number_integer())
      fail("obs_terms", "entry " + t.dump() + " is not [name, size]");
    ObsTerm term{t[0].get<std::string>(), t[1].get<int>()};
    const int expected = obs_term_size(term.name);
    if (expected < 0) fail("obs_terms", "unknown term '" + term.name + "'");
    if (term.size != expected)
      fail("obs_terms",
           "term '" + term.name + "' has size " + std::to_string(term.size) + ", expected " + std::to_string(expected));
    for (const ObsTerm& seen : a.obs_terms)
      if (seen.name == term.name) fail("obs_terms", "term '" + term.name + "' listed twice");
    a.obs_size += term.size;
    a.obs_terms.push_back(term);
  }

  const json joints = parse_meta_value(meta, "joint_names");
  if (!joints.is_array() || joints.size() != kJoints)
    fail("joint_names", "expected " + std::to_string(kJoints) + " names");
  for (std::size_t i = 0; i < kJoints; ++i)
    if (joints[i] != t1::kJointNames[i])
      fail("joint_names", "index " + std::to_string(i) + " is " + joints[i].dump() + ", runtime order has \"" +
                              t1::kJointNames[i] + "\"");

  a.default_pose = joint_floats(parse_meta_value(meta, "default_pose"), "default_pose");
  check_default_pose(a.default_pose);
  const json scale = parse_meta_value(meta, "action_scale");
  if (scale.is_number()) a.action_scale.fill(static_cast<float>(finite_number(scale, "action_scale")));
  else a.action_scale = joint_floats(scale, "action_scale");
  check_action_scale(a.action_scale);
  a.kp = joint_floats(parse_meta_value(meta, "kp"), "kp");
  a.kd = joint_floats(parse_meta_value(meta, "kd"), "kd");
  check_gains(a.kp, T1_KP_MAX, "kp");
  check_gains(a.kd, T1_KD_MAX, "kd");

  a.control_dt_s = finite_number(parse_meta_value(meta, "control_dt"), "control_dt");
  if (std::fabs(a.control_dt_s - kLoopDtS * kPolicyDecimation) > kControlDtToleranceS)
    fail("control_dt", std::to_string(a.control_dt_s) + " s != loop dt 0.002 s x decimation 10 = 0.02 s");
  a.gait_frequency_hz = finite_number(parse_meta_value(meta, "gait_frequency"), "gait_frequency");
  if (a.gait_frequency_hz < 0.0 || a.gait_frequency_hz > kMaxGaitFrequencyHz)
    fail("gait_frequency",
         std::to_string(a.gait_frequency_hz) + " Hz outside [0, " + std::to_string(kMaxGaitFrequencyHz) + "]");
  a.phase_freeze_command_norm =
      finite_number(parse_meta_value(meta, "phase_freeze_command_norm"), "phase_freeze_command_norm");
  if (a.phase_freeze_command_norm < 0.0 || a.phase_freeze_command_norm > kMaxCommandMagnitude)
    fail("phase_freeze_command_norm",
         std::to_string(a.phase_freeze_command_norm) + " outside [0, " + std::to_string(kMaxCommandMagnitude) + "]");

  const json ranges = parse_meta_value(meta, "command_ranges");
  const char* kAxes[3] = {"vx", "vy", "yaw_rate"};
  if (!ranges.is_object()) fail("command_ranges", "expected an object with vx, vy, yaw_rate");
  for (int i = 0; i < 3; ++i) {
    const std::string field = std::string("command_ranges.") + kAxes[i];
    if (!ranges.contains(kAxes[i]) || !ranges[kAxes[i]].is_array() || ranges[kAxes[i]].size() != 2)
      fail(field, "expected [lo, hi]");
    const double lo = finite_number(ranges[kAxes[i]][0], field), hi = finite_number(ranges[kAxes[i]][1], field);
    if (lo > hi) fail(field, "lo > hi");
    if (std::fabs(lo) > kMaxCommandMagnitude || std::fabs(hi) > kMaxCommandMagnitude)
      fail(field, "|bound| above the documented maximum " + std::to_string(kMaxCommandMagnitude));
    a.command_ranges[i] = {static_cast<float>(lo), static_cast<float>(hi)};
  }
  if (meta.count("obs_scales") && !parse_meta_value(meta, "obs_scales").is_object())
    fail("obs_scales", "expected an object");
  const json trained = parse_meta_value(meta, "trained");
  if (!trained.is_boolean()) fail("trained", "expected true/false");
  a.trained = trained.get<bool>();
  const json prov = parse_meta_value(meta, "provenance");
  if (!prov.is_object()) fail("provenance", "expected an object");
  a.provenance_json = prov.dump();

  // Tensors: layers.0 .. layers.L-1 contiguous, shapes chain from obs_size to the output rule's width.
  std::size_t num_layers = 0;
  while (tensors.count("layers." + std::to_string(num_layers) + ".weight")) ++num_layers;
  if (num_layers == 0) fail("layers.0.weight", "missing tensor");
  int64_t in = a.obs_size;
  for (std::size_t i = 0; i < num_layers; ++i) {
    const std::string w = "layers." + std::to_string(i) + ".weight", b = "layers." + std::to_string(i) + ".bias";
    const TensorView& wt = tensor(tensors, w);
    if (wt.shape.size() != 2 || wt.shape[1] != in || wt.shape[0] <= 0)
      fail(w, "shape must be (out, " + std::to_string(in) + ")" +
                  (i == 0 ? " (in = obs size = sum of obs_terms)" : " (in = previous out)"));
    DenseLayer layer;
    // File is row-major (out, in); map it that way, then copy into Eigen's column-major matrix.
    layer.weight = Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
        reinterpret_cast<const float*>(wt.bytes.data()), wt.shape[0], wt.shape[1]);
    if (!layer.weight.allFinite()) fail(w, "contains NaN or Inf");
    layer.bias = finite_vector(tensor(tensors, b), b, wt.shape[0]);
    in = wt.shape[0];
    a.layers.push_back(std::move(layer));
  }
  const int64_t expected_out = a.output_rule == OutputRule::kTanhNormal ? 2 * static_cast<int64_t>(kJoints) : kJoints;
  if (in != expected_out)
    fail("layers." + std::to_string(num_layers - 1) + ".weight",
         "output width " + std::to_string(in) + ", output rule needs " + std::to_string(expected_out));
  a.action_size = static_cast<int>(kJoints);
  a.obs_mean = finite_vector(tensor(tensors, "obs_mean"), "obs_mean", a.obs_size);
  a.obs_std = finite_vector(tensor(tensors, "obs_std"), "obs_std", a.obs_size);
  if ((a.obs_std.array() <= 0.0f).any()) fail("obs_std", "must be strictly positive");
  for (const auto& kv : tensors) {
    const std::string& n = kv.first;
    const bool known =
        n == "obs_mean" || n == "obs_std" ||
        std::any_of(a.layers.begin(), a.layers.end(), [&, i = std::size_t{0}](const DenseLayer&) mutable {
          const std::string p = "layers." + std::to_string(i++) + ".";
          return n == p + "weight" || n == p + "bias";
        });
    if (!known) fail(n, "unexpected tensor");
  }

  if (unreferenced_bytes > 0)
    fail("data",
         std::to_string(unreferenced_bytes) + " data bytes belong to no tensor entry (a tensor entry removed?)");

  const json hash = parse_meta_value(meta, "content_hash");
  if (!hash.is_string()) fail("content_hash", "expected a sha256 hex string");
  std::string concat;  // std::map iterates in sorted name order, as the contract requires
  for (const auto& kv : tensors) concat += kv.second.bytes;
  const std::string actual = sha256_hex(concat);
  if (hash.get<std::string>() != actual)
    fail("content_hash", "manifest says " + hash.get<std::string>() + ", tensors hash to " + actual);
  a.content_hash = actual;
  return a;
}

}  // namespace t1rt
