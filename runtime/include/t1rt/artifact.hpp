// Policy artifact (policies/ARTIFACT.md, schema 1): a validated, immutable description of one policy.
#pragma once
#include <Eigen/Core>
#include <array>
#include <stdexcept>
#include <string>
#include <vector>

#include "t1rt/activation.hpp"
#include "t1rt/constants.hpp"

namespace t1rt {

enum class OutputRule { kTanhNormal, kLinear };

struct ObsTerm {
  std::string name;
  int size = 0;
};

struct DenseLayer {
  Eigen::MatrixXf weight;  // (out, in)
  Eigen::VectorXf bias;    // (out)
};

using JointArray = std::array<float, kJoints>;

struct PolicyArtifact {
  std::string path;
  int schema_version = 0;
  std::string name;
  Activation activation = Activation::kSwish;
  OutputRule output_rule = OutputRule::kLinear;
  std::vector<ObsTerm> obs_terms;
  int obs_size = 0;
  int action_size = 0;  // always kJoints: one action per joint
  std::vector<DenseLayer> layers;
  Eigen::VectorXf obs_mean, obs_std;
  JointArray default_pose{};  // [rad]
  JointArray action_scale{};  // [rad per unit action]
  JointArray kp{};            // [N·m/rad]
  JointArray kd{};            // [N·m·s/rad]
  double control_dt_s = 0.0;
  double gait_frequency_hz = 0.0;
  double phase_freeze_command_norm = 0.0;
  std::array<std::array<float, 2>, 3> command_ranges{};  // vx [m/s], vy [m/s], yaw_rate [rad/s]: lo, hi
  bool trained = false;
  std::string provenance_json;
  std::string content_hash;  // sha256 hex, verified against the tensor bytes
};

// Thrown for every validation failure; field() names the offending field or tensor.
class ArtifactError : public std::runtime_error {
 public:
  ArtifactError(const std::string& field, const std::string& problem)
      : std::runtime_error("policy artifact field '" + field + "': " + problem), field_(field) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

// Reads and validates every field of the artifact at `path`; throws ArtifactError (or nothing).
PolicyArtifact load_artifact(const std::string& path);
// The same for the bytes of the file at `path`, already read (PolicyStore: the bytes it hashed).
PolicyArtifact parse_artifact(const std::string& path, const std::string& file);

// Canonical size of a known observation term; -1 if the name is unknown.
int obs_term_size(const std::string& name);

// sha256 hex digest (used for content_hash; exposed for tests that write artifacts).
std::string sha256_hex(const std::string& bytes);

}  // namespace t1rt
