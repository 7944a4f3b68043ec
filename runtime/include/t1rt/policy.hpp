// Observation builder, normaliser, MLP and gait clock: everything between the robot state and the joint
// targets. All buffers are allocated in the constructor; step() does no heap allocation.
#pragma once
#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

#include "t1rt/artifact.hpp"
#include "t1rt/mlp_kernel.hpp"

namespace t1rt {

// Inputs of one observation, in runtime joint order.
struct ObsInputs {
  const float* imu_quat = nullptr;     // 4, (w x y z)
  const float* gyro = nullptr;         // 3 [rad/s]
  const float* command = nullptr;      // 3: vx [m/s], vy [m/s], yaw_rate [rad/s]
  const float* q = nullptr;            // 23 [rad]
  const float* dq = nullptr;           // 23 [rad/s]
  const float* last_action = nullptr;  // 23
  const float* gait_phase = nullptr;   // 2: phi_left, phi_right [rad]
};

// Writes the manifest's terms in order into `out` (size = artifact obs_size).
void build_observation(const PolicyArtifact& artifact, const ObsInputs& in, Eigen::Ref<Eigen::VectorXf> out);

// Gravity direction in the IMU frame: R(quat)^T (0, 0, -1); the quaternion is normalised first.
void projected_gravity(const float* quat_wxyz, float* out3);

// The Booster IMU reports roll / pitch / yaw, not a quaternion. Convention (the aerospace / ROS one):
// Z-Y-X intrinsic, R = Rz(yaw) Ry(pitch) Rx(roll) maps IMU-frame vectors to the world (x forward, y left,
// z up): positive pitch tips the nose (x) down, positive roll lifts the left side (y) up.
// quat_from_rpy gives that R as (w x y z); the DDS transport feeds it to the same
// observation code as the LCM transport's quaternion.
void quat_from_rpy(const float* rpy, float* quat_wxyz);
// R(rpy)^T (0, 0, -1) in closed form: (sin p, -sin r cos p, -cos r cos p). Equals
// projected_gravity(quat_from_rpy(rpy)); yaw does not enter.
void gravity_from_rpy(const float* rpy, float* out3);

// Two-foot gait clock. Offsets (0, pi); wrapped to [-pi, pi); frozen while the command is near zero.
class GaitPhase {
 public:
  void reset();
  void advance(double frequency_hz, double control_dt_s, const float* command3, double freeze_norm);
  const float* phase() const { return phase_.data(); }

 private:
  std::array<float, 2> phase_{0.0f, static_cast<float>(-M_PI)};  // offsets (0, pi), pi wrapped to -pi
};

// Dense MLP: the artifact's weights repacked for the kernel variant (mlp_kernel.hpp) chosen at construction;
// every buffer is allocated in the constructor.
class Mlp {
 public:
  explicit Mlp(const PolicyArtifact& artifact, const mlp_kernel::Variant& variant = mlp_kernel::selected_variant());
  // Returns the action (size kJoints) after the output rule.
  const Eigen::VectorXf& run(const Eigen::VectorXf& input);
  const char* variant_name() const { return variant_.name; }
  // Reads every packed weight once, so the next run() finds them in cache: for the idle time before a
  // policy tick, when other work since the last one may have evicted them.
  void warm_cache() const;

 private:
  const mlp_kernel::Variant& variant_;
  std::vector<float> storage_;     // packed panels and biases of every layer, cache-line aligned
  const float* packed_ = nullptr;  // their first value (aligned), packed_size_ values
  std::size_t packed_size_ = 0;
  std::vector<mlp_kernel::PackedLayer> layers_;
  std::vector<std::vector<float>> outputs_;  // one per layer, padded to whole panels
  std::vector<float*> output_ptrs_;
  mlp_kernel::Net net_;
  Eigen::VectorXf action_;
};

// One loaded policy: artifact + buffers. Built off the loop thread, swapped in at a policy tick.
class PolicyEngine {
 public:
  explicit PolicyEngine(PolicyArtifact artifact);
  const PolicyArtifact& artifact() const { return artifact_; }
  void reset();  // last action = 0, gait phase to its offsets (on entering POLICY)
  // One policy tick: obs -> normalised obs -> action -> q_target. Returns false if the observation or
  // the action is non-finite (the supervisor faults; q_target is then not updated).
  enum class Result { kOk, kNonFiniteObs, kNonFiniteAction };
  Result step(const float* imu_quat, const float* gyro, const float* command, const float* q, const float* dq);
  const Eigen::VectorXf& obs_raw() const { return obs_raw_; }
  const Eigen::VectorXf& obs_normalized() const { return obs_norm_; }
  void warm_cache() const { mlp_.warm_cache(); }  // Mlp::warm_cache
  const char* mlp_variant() const { return mlp_.variant_name(); }
  // Composite mode, for the member that did NOT act this policy tick: its clock follows, and its
  // last_action becomes the applied joint targets [rad] in ITS action map, clip((q - pose) / scale, -1, 1),
  // as the stitched teacher hands each expert the env's one last action (training/distill/teacher.py). The members'
  // maps differ (joystick 0.5 rad per unit, getup up to 2): read raw, the other member's action would
  // mean other targets. No MLP is run.
  void follow(const JointArray& applied_q_target, const float* command);
  const JointArray& action() const { return last_action_; }
  const JointArray& q_target() const { return q_target_; }
  const GaitPhase& gait() const { return gait_; }
  // Test hook: the next step's action is replaced by NaN (fault-injection of the action path).
  void inject_nan_action_once() { inject_nan_action_ = true; }

 private:
  PolicyArtifact artifact_;
  Mlp mlp_;
  GaitPhase gait_;
  Eigen::VectorXf obs_raw_, obs_norm_;
  JointArray last_action_{}, q_target_{};
  bool inject_nan_action_ = false;
};

}  // namespace t1rt
