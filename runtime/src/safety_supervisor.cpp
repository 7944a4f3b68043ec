// The safety supervisor: the single source of truth for every safety rule of the runtime
// (ARCHITECTURE.md "Safety supervisor"). No heap use: fixed arrays and snprintf into fixed buffers.
// The rules R1-R12 this file implements, and why their values: the comment at the top of t1rt/safety.hpp (R3's
// per-stream sequence bookkeeping, SeqTracker, is seq_tracker.cpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "t1_motor_protocol.h"
#include "t1rt/prepare_gains.hpp"
#include "t1rt/safety.hpp"

namespace t1rt {

namespace {
// Motor status bits that mean the motor is not executing our command: FAULT. OVER_LIMIT (torque saturated
// or beyond a soft stop) is expected during falls and getups (t1_motor_protocol.h section 7): a warning only.
// POWER_ON and DAMPING (rule R4) mean the motor has reset or damps on its own: it ignores our command.
constexpr int32_t kMotorFaultMask = T1_STATUS_NOT_FOLLOWING | T1_STATUS_BAD_FRAME | T1_STATUS_BAD_SENSOR;
constexpr int32_t kMotorInfoMask = T1_STATUS_OVER_LIMIT;
constexpr double kNever = std::numeric_limits<double>::infinity();
// One q code of the reply (t1_motor_protocol.h §5) [rad], and R9's motion low-pass gain per 2 ms state.
constexpr float kQQuantumRad = 2.0f * T1_Q_MAX_RAD / static_cast<float>((1u << T1_Q_BITS) - 1u);
constexpr float kMotionFilterGain = static_cast<float>(kLoopDtS) / kBodyMotionTimeConstantS;

bool all_finite(const float* v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i])) return false;
  return true;
}
constexpr bool gains_within(const JointArray& gains, float max) {
  for (float g : gains)
    if (!(g >= 0.0f && g <= max)) return false;
  return true;
}
static_assert(gains_within(kPrepareKp, T1_KP_MAX) && gains_within(kPrepareKd, T1_KD_MAX),
              "PREPARE gains must fit the motor command frame's kp/kd range");
bool commanding(Mode m) { return m == Mode::kPrepare || m == Mode::kPolicy; }
constexpr float kNoLimit = std::numeric_limits<float>::infinity();  // an interval's open end
// The point of [lo, hi] nearest to x; an empty interval (lo > hi) is never passed in.
float nearest_in(float x, float lo, float hi) { return std::min(std::max(x, lo), hi); }
// [lo, hi] narrowed to [a, b] as far as it reaches: past it, only its end nearest to [a, b] is left.
void narrow(float& lo, float& hi, float a, float b) {
  if (b < lo) hi = lo;
  else if (a > hi) lo = hi;
  else lo = std::max(lo, a), hi = std::min(hi, b);
}
}  // namespace

Supervisor::Supervisor(const SafetyConfig& config) : cfg_(config) {
  prepare_total_ticks_ = std::max<int64_t>(1, std::llround(cfg_.prepare_duration_s / kLoopDtS));
}

void Supervisor::set_info(const char* text) { std::snprintf(last_info_.data(), last_info_.size(), "%s", text); }

void Supervisor::fault(int32_t bit, const char* reason) {
  latched_bits_ |= bit;
  std::snprintf(last_fault_.data(), last_fault_.size(), "%s", reason);
  if (mode_ != Mode::kFault) mode_ = Mode::kFault;
  std::snprintf(last_info_.data(), last_info_.size(), "FAULT: %s", reason);  // rule R7
}

// request_mode is the operator's (autostart makes its own requests in autostart_request): rule R1.
void Supervisor::request_mode(Mode target) {
  requested_ = target;
  has_request_ = true;
  operator_hold_ = target == Mode::kPassive || target == Mode::kDamping;
}

// Rule R12: one state source. A frame R3 would take as a restart, or a jump far ahead, while the followed
// stream is alive is a second publisher (a log replay, another simulator, a forger): FAULT, never adopted.
bool Supervisor::accept_state_seq(StateSource& source, SeqTracker& tracker, int64_t seq, double now_s) {
  const SeqTracker::Step step = tracker.step(seq);
  const bool alive = source.have && now_s - source.last_s < cfg_.restart_quiet_s;
  const bool restart = step == SeqTracker::Step::kRestart;
  const bool jump =
      step == SeqTracker::Step::kNew && tracker.newest() >= 0 && seq - tracker.newest() > cfg_.max_seq_jump_frames;
  if (alive && (restart || jump)) {
    ++second_source_frames_;
    std::snprintf(second_source_.data(), second_source_.size(),
                  "second state source on %s: seq %lld %s the followed stream at seq %lld, alive %.0f ms ago",
                  source.channel, static_cast<long long>(seq), restart ? "behind" : "far ahead of",
                  static_cast<long long>(tracker.newest()), (now_s - source.last_s) * 1e3);
    if (!(latched_bits_ & fault_bit::kSecondStateSource)) fault(fault_bit::kSecondStateSource, second_source_.data());
    return false;
  }
  if (!tracker.accept(seq)) return false;
  source.have = true;
  source.last_s = now_s;
  return true;
}

// Rule R11: estop from anyone (it only ever damps); everything else from an authorised sender only.
bool Supervisor::admits(OperatorInput input, bool authorised) { return input == OperatorInput::kEstop || authorised; }

void Supervisor::estop() {
  has_request_ = false;
  operator_hold_ = true;
  if (mode_ != Mode::kFault) mode_ = Mode::kDamping;
  set_info("estop: DAMPING (autostart held until reset or set_mode)");
}

void Supervisor::reset() {
  operator_hold_ = false;
  if (mode_ != Mode::kFault) return;
  mode_ = Mode::kDamping;
  latched_bits_ = 0;
  has_request_ = false;
  set_info("reset: FAULT cleared, DAMPING");
}

void Supervisor::gate_joystick(double now_s, bool have, double stamp_s, const float* in3,
                               const std::array<std::array<float, 2>, 3>& ranges, float* out3) {  // rule R5
  const bool stale = !have || now_s - stamp_s > cfg_.joystick_stale_s || !all_finite(in3, 3);
  for (int i = 0; i < 3; ++i) out3[i] = stale ? 0.0f : nearest_in(in3[i], ranges[i][0], ranges[i][1]);
  warning_bits_ = stale ? (warning_bits_ | fault_bit::kJoystickStale) : (warning_bits_ & ~fault_bit::kJoystickStale);
}

// Autostart's request for this tick (rule R1: none while the operator holds, none out of FAULT). It leaves
// PASSIVE only once every state stream is live, so a runtime started before the robot waits, not faults.
void Supervisor::autostart_request(const StateView& s) {
  if (!autostart_ || operator_hold_ || has_request_) return;
  const bool streams_live = s.have_imu && s.have_joint && (!s.needs_sim_status || s.have_sim_status);
  Mode next = mode_;
  if (mode_ == Mode::kPassive && streams_live) next = Mode::kDamping;
  else if (mode_ == Mode::kDamping) next = Mode::kPrepare;
  else if (mode_ == Mode::kPrepare && prepare_done()) next = Mode::kPolicy;
  if (next == mode_) return;
  requested_ = next;
  has_request_ = true;
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

bool Supervisor::begin_tick(const StateView& s, const PolicyArtifact& /*artifact*/) {
  entered_policy_ = false;
  warning_bits_ &=
      ~(fault_bit::kImuHold | fault_bit::kJointHold | fault_bit::kSimStatusHold | fault_bit::kMotorWarning |
        fault_bit::kMotorOverLimit | fault_bit::kTargetClamped | fault_bit::kRateLimited | fault_bit::kTorqueClamped);
  const double imu_age = s.have_imu ? s.now_s - s.imu_time_s : kNever;
  const double joint_age = s.have_joint ? s.now_s - s.joint_time_s : kNever;
  const double sim_age = !s.needs_sim_status ? 0.0 : s.have_sim_status ? s.now_s - s.sim_status_time_s : kNever;
  const bool imu_fresh = imu_age <= cfg_.hold_age_s, joint_fresh = joint_age <= cfg_.hold_age_s,
             sim_fresh = sim_age <= cfg_.hold_age_s;
  if (!imu_fresh) warning_bits_ |= fault_bit::kImuHold;
  if (!joint_fresh) warning_bits_ |= fault_bit::kJointHold;
  if (!sim_fresh) warning_bits_ |= fault_bit::kSimStatusHold;
  if (s.needs_sim_status && s.have_sim_status && !(std::isfinite(s.waist_height_m) && std::isfinite(s.trunk_height_m)))
    fault(fault_bit::kNonFiniteSimStatus, "non-finite waist_height or trunk_height in sim_status_t (switched mode)");

  // Non-finite state is a sensor failure whatever the mode.
  if ((s.have_imu && (!all_finite(s.quat, 4) || !all_finite(s.gyro, 3))) ||
      (s.have_joint && (!all_finite(s.q, kJoints) || !all_finite(s.dq, kJoints))))
    fault(fault_bit::kNonFiniteState, "non-finite value in imu_t or joint_state_t");

  int32_t watch_bit = 0;
  char watch_why[144] = "";
  const int watched = watch_motors(s, &watch_bit, watch_why, sizeof(watch_why));  // rules R8, R9, R10

  int motor_index = -1;  // the first motor whose status is a fault
  for (std::size_t i = 0; s.have_joint && i < kJoints && motor_index < 0; ++i) {
    if (s.motor_status[i] & kMotorInfoMask) warning_bits_ |= fault_bit::kMotorOverLimit;
    if (s.motor_status[i] & kMotorFaultMask) motor_index = static_cast<int>(i);
  }

  if (mode_ != Mode::kPassive && mode_ != Mode::kFault) {
    // Ages are checked whenever the runtime commands the motors; PASSIVE sends nothing that could hurt.
    char why[128];
    if (imu_age > cfg_.fault_age_s) {
      std::snprintf(why, sizeof(why), "imu_t stale: age %.1f ms > %.1f ms", imu_age * 1e3, cfg_.fault_age_s * 1e3);
      fault(fault_bit::kImuStale, why);
    } else if (joint_age > cfg_.fault_age_s) {
      std::snprintf(why, sizeof(why), "joint_state_t stale: age %.1f ms > %.1f ms", joint_age * 1e3,
                    cfg_.fault_age_s * 1e3);
      fault(fault_bit::kJointStale, why);
    } else if (sim_age > cfg_.fault_age_s) {
      std::snprintf(why, sizeof(why),
                    "sim_status_t stale: age %.1f ms > %.1f ms (switched mode: sim --status-rate 500)", sim_age * 1e3,
                    cfg_.fault_age_s * 1e3);
      fault(fault_bit::kSimStatusStale, why);
    } else if (motor_index >= 0) {
      std::snprintf(why, sizeof(why), "motor %d (%s) status 0x%x", motor_index, T1_MOTORS[motor_index].name,
                    static_cast<unsigned>(s.motor_status[motor_index]));
      // In DAMPING the command already equals the firmware's own fault reaction: warn, but block PREPARE.
      if (commanding(mode_)) fault(fault_bit::kMotorFault, why);
      else warning_bits_ |= fault_bit::kMotorWarning;
    } else if (watched >= 0) {
      if (commanding(mode_)) fault(watch_bit, watch_why);
      else warning_bits_ |= fault_bit::kMotorWarning;
    }
  } else if (mode_ == Mode::kPassive && watched >= 0) {
    warning_bits_ |= fault_bit::kMotorWarning;
  }

  autostart_request(s);
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
        else if (motor_index >= 0) set_info("set_mode prepare refused: motor fault bits set");
        else if (watched >= 0)
          std::snprintf(last_info_.data(), last_info_.size(), "set_mode prepare refused: %s", watch_why);
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

// Rules R8-R10, advanced once per new joint state (a tick that reuses the state counts nothing).
void Supervisor::advance_watch(const StateView& s) {
  if (!s.have_joint || s.joint_time_s == watched_joint_time_s_) return;
  watched_joint_time_s_ = s.joint_time_s;
  // R9's evidence that the robot moves, low-passed: the IMU's angular rate and the motors' mean speed.
  if (s.have_imu && all_finite(s.gyro, 3)) {
    const float rate = std::sqrt(s.gyro[0] * s.gyro[0] + s.gyro[1] * s.gyro[1] + s.gyro[2] * s.gyro[2]);
    body_rate_radps_ += kMotionFilterGain * (rate - body_rate_radps_);
  }
  if (all_finite(s.dq, kJoints)) {
    float speed = 0.0f;
    for (std::size_t i = 0; i < kJoints; ++i) speed += std::fabs(s.dq[i]);
    joint_speed_radps_ += kMotionFilterGain * (speed / static_cast<float>(kJoints) - joint_speed_radps_);
  }
  const bool body_moves = body_rate_radps_ > kBodyMotionMinRateRadS && joint_speed_radps_ > kJointMotionMinSpeedRadS;
  for (std::size_t i = 0; i < kJoints; ++i) {
    MotorWatch& w = watch_[i];
    if (s.motor_status[i] & T1_STATUS_NO_REPLY) {  // no reading this cycle: R9 and R10 wait for one
      ++w.silent_cycles;
      continue;
    }
    w.silent_cycles = 0;
    const t1_motor_info_t& m = T1_MOTORS[i];
    const float q = s.q[i];
    // A state not newer than this motor's last reply is a publisher restart: no reading to compare with.
    const bool have_prev = w.have_q && s.joint_seq > w.last_seq;
    // R10: further past the range, or faster, than any joint of the model went in falls, getups and pushes.
    const bool outside = q < m.q_min_rad - kImpossibleRangeMarginRad || q > m.q_max_rad + kImpossibleRangeMarginRad;
    const float v_max = kImpossibleSpeedFactor * T1_CLASS_RANGES[m.motor_class].v_max_rads;  // [rad/s]
    const float gap_s = have_prev ? static_cast<float>(s.joint_seq - w.last_seq) * static_cast<float>(kLoopDtS) : 0.0f;
    const float max_step = have_prev ? v_max * gap_s + kImpossibleJumpQuanta * kQQuantumRad : kNoLimit;
    const bool jumped = std::fabs(q - w.last_q) > max_step;
    w.impossible = outside ? MotorWatch::kOutside : jumped ? MotorWatch::kJump : MotorWatch::kPlausible;
    w.impossible_from = w.last_q;
    w.impossible_ms = gap_s * 1e3f;
    // R9: still under load, away from the stops that would explain it, while the body moves.
    const float tau = cmd_kp_[i] * (cmd_q_[i] - q) - cmd_kd_[i] * s.dq[i];  // dq_des = tau_ff = 0
    const bool loaded = std::fabs(tau) > frozen_encoder_torque_nm(m.torque_limit_nm);
    const bool off_stops =
        q > m.q_min_rad + kFrozenEncoderStopMarginRad && q < m.q_max_rad - kFrozenEncoderStopMarginRad;
    const bool same = have_prev && std::memcmp(&w.last_q, &q, sizeof(float)) == 0;
    w.frozen_cycles = same && loaded && off_stops && body_moves ? w.frozen_cycles + 1 : 0;
    w.have_q = true;
    w.last_q = q;
    w.last_seq = s.joint_seq;
  }
}

// The first motor that breaks R8, R9 or R10 now (-1: none), with its fault bit and the reason naming it.
int Supervisor::watch_motors(const StateView& s, int32_t* bit, char* why, std::size_t why_size) {
  advance_watch(s);
  for (std::size_t i = 0; s.have_joint && i < kJoints; ++i) {
    const MotorWatch& w = watch_[i];
    const t1_motor_info_t& m = T1_MOTORS[i];
    const int motor = static_cast<int>(i);
    if (w.silent_cycles > kMotorSilentMaxCycles) {
      *bit = fault_bit::kMotorSilent;
      std::snprintf(why, why_size, "motor %d (%s) silent: no reply for %d bus cycles (> %d)", motor, m.name,
                    static_cast<int>(w.silent_cycles), kMotorSilentMaxCycles);
      return motor;
    }
    if (w.impossible != MotorWatch::kPlausible) {
      *bit = fault_bit::kImpossibleReading;
      if (w.impossible == MotorWatch::kOutside)
        std::snprintf(why, why_size, "motor %d (%s) impossible reading: q %.3f rad, range %.2f..%.2f rad (+- %.2f)",
                      motor, m.name, static_cast<double>(w.last_q), static_cast<double>(m.q_min_rad),
                      static_cast<double>(m.q_max_rad), static_cast<double>(kImpossibleRangeMarginRad));
      else
        std::snprintf(why, why_size, "motor %d (%s) impossible reading: q %.3f -> %.3f rad in %.0f ms (> %.1f rad/s)",
                      motor, m.name, static_cast<double>(w.impossible_from), static_cast<double>(w.last_q),
                      static_cast<double>(w.impossible_ms),
                      static_cast<double>(kImpossibleSpeedFactor * T1_CLASS_RANGES[m.motor_class].v_max_rads));
      return motor;
    }
    if (w.frozen_cycles > kFrozenEncoderMaxCycles) {
      *bit = fault_bit::kEncoderFrozen;
      std::snprintf(why, why_size,
                    "motor %d (%s) encoder frozen: q bit-identical for %d replies under |PD torque| > %.1f N*m while "
                    "the body turned",
                    motor, m.name, static_cast<int>(w.frozen_cycles),
                    static_cast<double>(frozen_encoder_torque_nm(m.torque_limit_nm)));
      return motor;
    }
  }
  return -1;
}

void Supervisor::remember_command(const t1::joint_command_t& out) {
  std::copy(out.q_des, out.q_des + kJoints, cmd_q_.begin());
  std::copy(out.kp, out.kp + kJoints, cmd_kp_.begin());
  std::copy(out.kd, out.kd + kJoints, cmd_kd_.begin());
}

// Rule R6: rate, then torque, then range; each limit narrows the interval left by the ones before it.
void Supervisor::clamp_targets(const StateView& s, const JointArray& kps, const JointArray& kds, JointArray& target) {
  for (std::size_t i = 0; i < kJoints; ++i) {
    const t1_motor_info_t& m = T1_MOTORS[i];
    const float mid = 0.5f * (m.q_min_rad + m.q_max_rad);
    const float half = 0.5f * (m.q_max_rad - m.q_min_rad) * cfg_.joint_range_fraction;
    const float range_lo = mid - half, range_hi = mid + half;
    const float wanted = target[i];
    // 1. Rate: the allowed interval around the last target (without one, e.g. PREPARE's first tick
    //    where last_target_ = q, anything).
    float lo = -kNoLimit, hi = kNoLimit;
    if (have_last_target_) {
      lo = last_target_[i] - cfg_.max_target_step_rad;
      hi = last_target_[i] + cfg_.max_target_step_rad;
    }
    // 2. Torque: kp (t - q) - kd dq within +-limit  <=>  t in q + (kd dq +- limit) / kp.
    const float kp = kps[i], kd = kds[i];
    if (kp > 0.0f) {
      const float t_lo = s.q[i] + (kd * s.dq[i] - m.torque_limit_nm) / kp;
      const float t_hi = s.q[i] + (kd * s.dq[i] + m.torque_limit_nm) / kp;
      if (wanted < t_lo || wanted > t_hi || t_hi < lo || t_lo > hi) warning_bits_ |= fault_bit::kTorqueClamped;
      narrow(lo, hi, t_lo, t_hi);  // unreachable within the rate: the nearest rate-allowed point
    }
    // 3. Range, as far as reachable.
    if (wanted < range_lo || wanted > range_hi) warning_bits_ |= fault_bit::kTargetClamped;
    narrow(lo, hi, range_lo, range_hi);
    const float t = nearest_in(wanted, lo, hi);
    if (have_last_target_ && std::fabs(wanted - last_target_[i]) > cfg_.max_target_step_rad)
      warning_bits_ |= fault_bit::kRateLimited;
    target[i] = t;
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
  if (!commanding(mode_)) {  // PASSIVE: kp = kd = 0; DAMPING and FAULT: kp 0, the firmware's safe damping
    for (std::size_t i = 0; i < kJoints; ++i) {
      out.kp[i] = 0.0f;
      out.kd[i] = mode_ == Mode::kPassive ? 0.0f : T1_MOTORS[i].d_safe_nms;
    }
    have_last_target_ = false;
    remember_command(out);
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
  // PREPARE holds with the robot's stand-up gains (prepare_gains.hpp), POLICY with the policy's own.
  const JointArray& kp = mode_ == Mode::kPrepare ? kPrepareKp : a.kp;
  const JointArray& kd = mode_ == Mode::kPrepare ? kPrepareKd : a.kd;
  clamp_targets(s, kp, kd, target);
  last_target_ = target;
  have_last_target_ = true;
  for (std::size_t i = 0; i < kJoints; ++i) {
    out.q_des[i] = target[i];
    out.kp[i] = kp[i];
    out.kd[i] = kd[i];
  }
  remember_command(out);
}

}  // namespace t1rt
