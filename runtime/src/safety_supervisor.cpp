// The safety supervisor: the single source of truth for every safety rule of the runtime
// (ARCHITECTURE.md "Safety supervisor"). No heap use: fixed arrays and snprintf into fixed buffers.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "t1_motor_protocol.h"
#include "t1rt/safety.hpp"

namespace t1rt {

namespace {
// Motor status bits that mean the motor is not executing our command: FAULT. OVER_LIMIT (torque saturated
// or beyond a soft stop) is expected during falls and getups (t1_motor_protocol.h section 7): a warning only.
constexpr int32_t kMotorFaultMask = T1_STATUS_WATCHDOG | T1_STATUS_BAD_FRAME | T1_STATUS_BAD_SENSOR;
constexpr int32_t kMotorInfoMask = T1_STATUS_OVER_LIMIT;
constexpr double kNever = std::numeric_limits<double>::infinity();

bool all_finite(const float* v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i])) return false;
  return true;
}
bool commanding(Mode m) { return m == Mode::kPrepare || m == Mode::kPolicy; }
}  // namespace

const char* mode_name(Mode mode) {
  switch (mode) {
    case Mode::kPassive: return "PASSIVE";
    case Mode::kDamping: return "DAMPING";
    case Mode::kPrepare: return "PREPARE";
    case Mode::kPolicy: return "POLICY";
    case Mode::kFault: return "FAULT";
  }
  return "?";
}

bool parse_mode(const char* text, Mode* mode) {
  static const struct { const char* name; Mode mode; } kModes[] = {
      {"passive", Mode::kPassive}, {"damping", Mode::kDamping}, {"prepare", Mode::kPrepare}, {"policy", Mode::kPolicy}};
  for (const auto& m : kModes)
    if (std::strcmp(text, m.name) == 0) {
      *mode = m.mode;
      return true;
    }
  return false;
}

Supervisor::Supervisor(const SafetyConfig& config) : cfg_(config) {
  prepare_total_ticks_ = std::max<int64_t>(1, std::llround(cfg_.prepare_duration_s / kLoopDtS));
}

void Supervisor::set_info(const char* text) { std::snprintf(last_info_.data(), last_info_.size(), "%s", text); }

void Supervisor::fault(int32_t bit, const char* reason) {
  latched_bits_ |= bit;
  std::snprintf(last_fault_.data(), last_fault_.size(), "%s", reason);
  if (mode_ != Mode::kFault) mode_ = Mode::kFault;
}

void Supervisor::request_mode(Mode target) {
  requested_ = target;
  has_request_ = true;
}

void Supervisor::estop() {
  has_request_ = false;
  if (mode_ != Mode::kFault) mode_ = Mode::kDamping;
  set_info("estop: DAMPING");
}

void Supervisor::reset() {
  if (mode_ != Mode::kFault) return;
  mode_ = Mode::kDamping;
  latched_bits_ = 0;
  has_request_ = false;
  set_info("reset: FAULT cleared, DAMPING");
}

void Supervisor::note_imu_seq(int64_t seq) {
  if (last_imu_seq_ >= 0 && seq > last_imu_seq_ + 1) imu_gaps_ += seq - last_imu_seq_ - 1;
  last_imu_seq_ = seq;
}

void Supervisor::note_joint_seq(int64_t seq) {
  if (last_joint_seq_ >= 0 && seq > last_joint_seq_ + 1) joint_gaps_ += seq - last_joint_seq_ - 1;
  last_joint_seq_ = seq;
}

void Supervisor::gate_joystick(double now_s, bool have, double stamp_s, const float* in3, float* out3) {
  const bool stale = !have || now_s - stamp_s > cfg_.joystick_stale_s || !all_finite(in3, 3);
  for (int i = 0; i < 3; ++i) out3[i] = stale ? 0.0f : in3[i];
  warning_bits_ = stale ? (warning_bits_ | fault_bit::kJoystickStale) : (warning_bits_ & ~fault_bit::kJoystickStale);
}

void Supervisor::enter(Mode mode, const StateView& state) {
  mode_ = mode;
  if (mode == Mode::kPrepare) {
    std::copy(state.q, state.q + kJoints, prepare_start_.begin());
    last_target_ = prepare_start_;
    have_last_target_ = true;
    prepare_ticks_ = 0;
  }
  if (mode == Mode::kPolicy) entered_policy_ = true;
  char text[96];
  std::snprintf(text, sizeof(text), "mode %s", mode_name(mode));
  set_info(text);
}

bool Supervisor::begin_tick(const StateView& s, const PolicyArtifact& artifact) {
  (void)artifact;
  entered_policy_ = false;
  warning_bits_ &= ~(fault_bit::kImuHold | fault_bit::kJointHold | fault_bit::kSimStatusHold | fault_bit::kMotorWarning | fault_bit::kMotorOverLimit |
                     fault_bit::kTargetClamped | fault_bit::kRateLimited | fault_bit::kTorqueClamped);
  const double imu_age = s.have_imu ? s.now_s - s.imu_time_s : kNever;
  const double joint_age = s.have_joint ? s.now_s - s.joint_time_s : kNever;
  const double sim_age = !s.needs_sim_status ? 0.0 : s.have_sim_status ? s.now_s - s.sim_status_time_s : kNever;
  const bool imu_fresh = imu_age <= cfg_.hold_age_s, joint_fresh = joint_age <= cfg_.hold_age_s;
  const bool sim_fresh = sim_age <= cfg_.hold_age_s;
  if (!imu_fresh) warning_bits_ |= fault_bit::kImuHold;
  if (!joint_fresh) warning_bits_ |= fault_bit::kJointHold;
  if (!sim_fresh) warning_bits_ |= fault_bit::kSimStatusHold;
  if (s.needs_sim_status && s.have_sim_status && !std::isfinite(s.waist_height_m))
    fault(fault_bit::kNonFiniteSimStatus, "non-finite waist_height in sim_status_t (composite mode)");

  // Non-finite state is a sensor failure whatever the mode.
  if ((s.have_imu && (!all_finite(s.quat, 4) || !all_finite(s.gyro, 3))) ||
      (s.have_joint && (!all_finite(s.q, kJoints) || !all_finite(s.dq, kJoints))))
    fault(fault_bit::kNonFiniteState, "non-finite value in imu_t or joint_state_t");

  bool motor_fault = false;
  int motor_index = -1;
  for (std::size_t i = 0; s.have_joint && i < kJoints; ++i) {
    if (s.motor_status[i] & kMotorInfoMask) warning_bits_ |= fault_bit::kMotorOverLimit;
    if (s.motor_status[i] & kMotorFaultMask) {
      motor_fault = true;
      motor_index = static_cast<int>(i);
      break;
    }
  }

  if (mode_ != Mode::kPassive && mode_ != Mode::kFault) {
    // Ages are checked whenever the runtime commands the motors; PASSIVE sends nothing that could hurt.
    char why[128];
    if (imu_age > cfg_.fault_age_s) {
      std::snprintf(why, sizeof(why), "imu_t stale: age %.1f ms > %.1f ms", imu_age * 1e3, cfg_.fault_age_s * 1e3);
      fault(fault_bit::kImuStale, why);
    } else if (joint_age > cfg_.fault_age_s) {
      std::snprintf(why, sizeof(why), "joint_state_t stale: age %.1f ms > %.1f ms", joint_age * 1e3, cfg_.fault_age_s * 1e3);
      fault(fault_bit::kJointStale, why);
    } else if (sim_age > cfg_.fault_age_s) {
      std::snprintf(why, sizeof(why), "sim_status_t stale: age %.1f ms > %.1f ms (composite mode: sim --status-rate 500)",
                    sim_age * 1e3, cfg_.fault_age_s * 1e3);
      fault(fault_bit::kSimStatusStale, why);
    } else if (motor_fault) {
      std::snprintf(why, sizeof(why), "motor %d (%s) status 0x%x", motor_index, T1_MOTORS[motor_index].name,
                    static_cast<unsigned>(s.motor_status[motor_index]));
      // In DAMPING the command already equals the firmware's own fault reaction: warn, but block PREPARE.
      if (commanding(mode_)) fault(fault_bit::kMotorFault, why);
      else warning_bits_ |= fault_bit::kMotorWarning;
    }
  }

  if (has_request_ && mode_ != Mode::kFault) {
    has_request_ = false;
    const bool fresh = imu_fresh && joint_fresh && sim_fresh;
    switch (requested_) {
      case Mode::kPassive:
      case Mode::kDamping:
        enter(requested_, s);
        break;
      case Mode::kPrepare:
        if (!fresh) set_info("set_mode prepare refused: state not fresh");
        else if (motor_fault) set_info("set_mode prepare refused: motor fault bits set");
        else if (mode_ == Mode::kPassive) set_info("set_mode prepare refused: go to DAMPING first");
        else enter(Mode::kPrepare, s);
        break;
      case Mode::kPolicy:
        if (mode_ == Mode::kPolicy) break;
        if (mode_ != Mode::kPrepare || !prepare_done()) set_info("set_mode policy refused: PREPARE ramp not finished");
        else if (!fresh) set_info("set_mode policy refused: state not fresh");
        else enter(Mode::kPolicy, s);
        break;
      case Mode::kFault:
        break;
    }
  }
  holding_ = !(imu_fresh && joint_fresh && sim_fresh);
  return mode_ == Mode::kPolicy && !holding_;
}

void Supervisor::clamp_targets(const StateView& s, const PolicyArtifact& a, JointArray& target) {
  for (std::size_t i = 0; i < kJoints; ++i) {
    const t1_motor_info_t& m = T1_MOTORS[i];
    const float mid = 0.5f * (m.q_min_rad + m.q_max_rad);
    const float half = 0.5f * (m.q_max_rad - m.q_min_rad) * cfg_.joint_range_fraction;
    const float lo = mid - half, hi = mid + half;
    float t = target[i];
    if (t < lo || t > hi) warning_bits_ |= fault_bit::kTargetClamped;
    t = std::clamp(t, lo, hi);
    if (have_last_target_) {
      const float step = cfg_.max_target_step_rad;
      const float limited = std::clamp(t, last_target_[i] - step, last_target_[i] + step);
      if (limited != t) warning_bits_ |= fault_bit::kRateLimited;
      t = limited;
    }
    // Expected motor torque kp (t - q) - kd dq must stay within the motor limit: move the target.
    const float kp = a.kp[i], kd = a.kd[i];
    const float tau = kp * (t - s.q[i]) - kd * s.dq[i];
    if (kp > 0.0f && std::fabs(tau) > m.torque_limit_nm) {
      const float tau_c = std::clamp(tau, -m.torque_limit_nm, m.torque_limit_nm);
      t = s.q[i] + (tau_c + kd * s.dq[i]) / kp;
      warning_bits_ |= fault_bit::kTorqueClamped;
    }
    target[i] = std::clamp(t, lo, hi);  // the range is the last word
  }
}

void Supervisor::finish_tick(const StateView& s, const PolicyArtifact& a, const JointArray& policy_target,
                             t1::joint_command_t& out) {
  out.mode = static_cast<int8_t>(mode_);
  for (std::size_t i = 0; i < kJoints; ++i) {
    out.dq_des[i] = 0.0f;
    out.tau_ff[i] = 0.0f;
    out.q_des[i] = s.have_joint && std::isfinite(s.q[i]) ? s.q[i] : 0.0f;
  }
  if (mode_ == Mode::kPassive) {
    for (std::size_t i = 0; i < kJoints; ++i) out.kp[i] = out.kd[i] = 0.0f;
    have_last_target_ = false;
    return;
  }
  if (!commanding(mode_)) {  // DAMPING and FAULT: kp 0, the firmware's safe damping
    for (std::size_t i = 0; i < kJoints; ++i) {
      out.kp[i] = 0.0f;
      out.kd[i] = T1_MOTORS[i].d_safe_nms;
    }
    have_last_target_ = false;
    return;
  }
  JointArray target = last_target_;  // holding: the last target
  if (!holding_) {
    if (mode_ == Mode::kPrepare) {
      prepare_ticks_ = std::min(prepare_ticks_ + 1, prepare_total_ticks_);
      const float f = static_cast<float>(prepare_ticks_) / static_cast<float>(prepare_total_ticks_);
      for (std::size_t i = 0; i < kJoints; ++i)
        target[i] = prepare_start_[i] + f * (a.default_pose[i] - prepare_start_[i]);
    } else {
      target = policy_target;
    }
  }
  clamp_targets(s, a, target);
  last_target_ = target;
  have_last_target_ = true;
  for (std::size_t i = 0; i < kJoints; ++i) {
    out.q_des[i] = target[i];
    out.kp[i] = a.kp[i];
    out.kd[i] = a.kd[i];
  }
}

}  // namespace t1rt
