#include "t1rt/policy.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace t1rt {

namespace {
constexpr double kTwoPi = 2.0 * M_PI;

// Wrap to [-pi, pi).
double wrap_pi(double x) {
  double y = std::fmod(x + M_PI, kTwoPi);
  if (y < 0) y += kTwoPi;
  return y - M_PI;
}

constexpr std::size_t kCacheLineFloats = 64 / sizeof(float);  // panels start on a cache line: no split loads

// Rows [0, rows) of `l` in the kernel's panel layout (mlp_kernel.hpp); the padding rows stay as they are (zero).
void pack_layer(const DenseLayer& l, int rows, float* panels, float* bias) {
  using mlp_kernel::kPanelRows;
  const Eigen::Index cols = l.weight.cols();
  for (int r = 0; r < rows; ++r) {
    bias[r] = l.bias[r];
    float* panel = panels + static_cast<std::ptrdiff_t>(r / kPanelRows) * cols * kPanelRows;
    for (Eigen::Index c = 0; c < cols; ++c) panel[c * kPanelRows + r % kPanelRows] = l.weight(r, c);
  }
}
}  // namespace

void projected_gravity(const float* quat_wxyz, float* out3) {
  double w = quat_wxyz[0], x = quat_wxyz[1], y = quat_wxyz[2], z = quat_wxyz[3];
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  if (n > 0.0) {
    w /= n;
    x /= n;
    y /= n;
    z /= n;
  }
  // R^T (0,0,-1) = -(third row of R) transposed.
  out3[0] = static_cast<float>(-2.0 * (x * z - w * y));
  out3[1] = static_cast<float>(-2.0 * (y * z + w * x));
  out3[2] = static_cast<float>(-(1.0 - 2.0 * (x * x + y * y)));
}

void quat_from_rpy(const float* rpy, float* q) {
  const double cr = std::cos(0.5 * rpy[0]), sr = std::sin(0.5 * rpy[0]);
  const double cp = std::cos(0.5 * rpy[1]), sp = std::sin(0.5 * rpy[1]);
  const double cy = std::cos(0.5 * rpy[2]), sy = std::sin(0.5 * rpy[2]);
  q[0] = static_cast<float>(cr * cp * cy + sr * sp * sy);
  q[1] = static_cast<float>(sr * cp * cy - cr * sp * sy);
  q[2] = static_cast<float>(cr * sp * cy + sr * cp * sy);
  q[3] = static_cast<float>(cr * cp * sy - sr * sp * cy);
}

void gravity_from_rpy(const float* rpy, float* out3) {
  const double r = rpy[0], p = rpy[1];
  out3[0] = static_cast<float>(std::sin(p));
  out3[1] = static_cast<float>(-std::sin(r) * std::cos(p));
  out3[2] = static_cast<float>(-std::cos(r) * std::cos(p));
}

void build_observation(const PolicyArtifact& a, const ObsInputs& in, Eigen::Ref<Eigen::VectorXf> out) {
  Eigen::Index k = 0;
  for (const ObsTerm& term : a.obs_terms) {
    const std::string& n = term.name;  // compared, never copied: no allocation
    if (n == "gyro") {
      for (int i = 0; i < 3; ++i) out[k++] = in.gyro[i];
    } else if (n == "gravity") {
      float g[3];
      projected_gravity(in.imu_quat, g);
      for (float v : g) out[k++] = v;
    } else if (n == "command") {
      for (int i = 0; i < 3; ++i) out[k++] = in.command[i];
    } else if (n == "joint_pos") {
      for (std::size_t i = 0; i < kJoints; ++i) out[k++] = in.q[i] - a.default_pose[i];
    } else if (n == "joint_vel") {
      for (std::size_t i = 0; i < kJoints; ++i) out[k++] = in.dq[i];
    } else if (n == "last_action") {
      for (std::size_t i = 0; i < kJoints; ++i) out[k++] = in.last_action[i];
    } else if (n == "phase") {
      out[k++] = std::cos(in.gait_phase[0]);
      out[k++] = std::cos(in.gait_phase[1]);
      out[k++] = std::sin(in.gait_phase[0]);
      out[k++] = std::sin(in.gait_phase[1]);
    }
  }
}

void GaitPhase::reset() { phase_ = {0.0f, static_cast<float>(-M_PI)}; }

void GaitPhase::advance(double frequency_hz, double control_dt_s, const float* command3, double freeze_norm) {
  const double norm = std::sqrt(double(command3[0]) * command3[0] + double(command3[1]) * command3[1] +
                                double(command3[2]) * command3[2]);
  if (norm < freeze_norm) return;
  const double step = kTwoPi * frequency_hz * control_dt_s;
  for (float& p : phase_) p = static_cast<float>(wrap_pi(double(p) + step));
}

Mlp::Mlp(const PolicyArtifact& artifact, const mlp_kernel::Variant& variant)
    : variant_(variant), action_(static_cast<Eigen::Index>(kJoints)) {
  // Rows computed per layer: all, except that the output rule reads only the first kJoints of the last one
  // (tanh_normal: the loc half; the scale half only matters in training).
  std::vector<int> used_rows;
  for (const DenseLayer& l : artifact.layers) used_rows.push_back(static_cast<int>(l.weight.rows()));
  used_rows.back() = static_cast<int>(kJoints);
  std::size_t total = 0;
  for (std::size_t i = 0; i < used_rows.size(); ++i)
    total += static_cast<std::size_t>(mlp_kernel::padded_rows(used_rows[i])) *
             static_cast<std::size_t>(artifact.layers[i].weight.cols() + 1);
  storage_.assign(total + kCacheLineFloats, 0.0f);
  float* next = storage_.data();
  while (reinterpret_cast<std::uintptr_t>(next) % (kCacheLineFloats * sizeof(float)) != 0) ++next;
  packed_ = next;
  packed_size_ = total;
  for (std::size_t i = 0; i < used_rows.size(); ++i) {
    const DenseLayer& l = artifact.layers[i];
    const int rows = used_rows[i], cols = static_cast<int>(l.weight.cols());
    const int padded = mlp_kernel::padded_rows(rows);
    float* panels = next;
    float* bias = panels + static_cast<std::ptrdiff_t>(padded) * cols;
    next = bias + padded;
    pack_layer(l, rows, panels, bias);
    layers_.push_back({panels, bias, rows, cols});
    outputs_.emplace_back(static_cast<std::size_t>(padded), 0.0f);
  }
  for (auto& o : outputs_) output_ptrs_.push_back(o.data());
  net_ = {layers_.data(), static_cast<int>(layers_.size()), artifact.activation,
          artifact.output_rule == OutputRule::kTanhNormal};
}

const Eigen::VectorXf& Mlp::run(const Eigen::VectorXf& input) {
  variant_.forward(net_, input.data(), output_ptrs_.data());
  const float* out = output_ptrs_.back();  // the first kJoints values: the action (tanh_normal: its loc half)
  std::copy(out, out + action_.size(), action_.data());
  return action_;
}

void Mlp::warm_cache() const {
  // One value per cache line into independent sums (no add waits for the one before); the volatile store
  // keeps the reads.
  constexpr std::size_t kSums = 4;
  float sum[kSums] = {};
  for (std::size_t i = 0; i + kSums * kCacheLineFloats <= packed_size_; i += kSums * kCacheLineFloats)
    for (std::size_t k = 0; k < kSums; ++k) sum[k] += packed_[i + k * kCacheLineFloats];
  volatile float sink = sum[0] + sum[1] + sum[2] + sum[3];
  (void)sink;
}

PolicyEngine::PolicyEngine(PolicyArtifact artifact)
    : artifact_(std::move(artifact)), mlp_(artifact_), obs_raw_(artifact_.obs_size), obs_norm_(artifact_.obs_size) {
  reset();
}

void PolicyEngine::reset() {
  last_action_.fill(0.0f);
  q_target_ = artifact_.default_pose;
  gait_.reset();
}

void PolicyEngine::follow(const JointArray& applied_q_target, const float* command) {
  gait_.advance(artifact_.gait_frequency_hz, artifact_.control_dt_s, command, artifact_.phase_freeze_command_norm);
  for (std::size_t i = 0; i < kJoints; ++i) {
    const float own = (applied_q_target[i] - artifact_.default_pose[i]) / artifact_.action_scale[i];
    last_action_[i] = std::clamp(own, -1.0f, 1.0f);
  }
}

PolicyEngine::Result PolicyEngine::step(const float* imu_quat, const float* gyro, const float* command, const float* q,
                                        const float* dq) {
  // The observation carries the clock as it stands; it advances after the step, with this tick's command,
  // exactly as the training envs do (reset observation = initial phase).
  ObsInputs in{imu_quat, gyro, command, q, dq, last_action_.data(), gait_.phase()};
  build_observation(artifact_, in, obs_raw_);
  obs_norm_ = (obs_raw_ - artifact_.obs_mean).cwiseQuotient(artifact_.obs_std);
  if (!obs_norm_.allFinite()) return Result::kNonFiniteObs;
  const Eigen::VectorXf& action = mlp_.run(obs_norm_);
  if (inject_nan_action_ || !action.allFinite()) {
    inject_nan_action_ = false;
    return Result::kNonFiniteAction;
  }
  for (std::size_t i = 0; i < kJoints; ++i) {
    last_action_[i] = action[static_cast<Eigen::Index>(i)];
    q_target_[i] = artifact_.default_pose[i] + artifact_.action_scale[i] * last_action_[i];
  }
  gait_.advance(artifact_.gait_frequency_hz, artifact_.control_dt_s, command, artifact_.phase_freeze_command_norm);
  return Result::kOk;
}

}  // namespace t1rt
