// The controller's telemetry: controller_status_t at 10 Hz, assembled from the loop's own counters into
// strings of reserved capacity (no allocation on the loop thread).
#include <cstdio>
#include <cstring>

#include "t1_contract.hpp"
#include "t1rt/controller.hpp"

namespace t1rt {

namespace {
constexpr std::size_t kStringReserve = Controller::kStatusStringReserve;
constexpr double kSToUs = 1e6, kSToMs = 1e3;

void assign_bounded(std::string& dst, const char* src) {
  const std::size_t n = std::min(std::strlen(src), dst.capacity());
  dst.assign(src, n);
}
}  // namespace

void Controller::format_policy_identity() {
  const PolicyArtifact& a = engine_->artifact();
  if (composite()) {
    const PolicyArtifact& u = members_[1]->artifact();
    std::snprintf(policy_name_, sizeof(policy_name_), "composite[getup=%s,upright=%s] active=%s", a.name.c_str(),
                  u.name.c_str(), member_name(member_));
    std::snprintf(policy_hash_, sizeof(policy_hash_), "%.32s+%.32s", a.content_hash.c_str(), u.content_hash.c_str());
  } else if (chain()) {
    const PolicyArtifact &rise = members_[1]->artifact(), &stand = members_[2]->artifact();
    std::snprintf(policy_name_, sizeof(policy_name_), "chain[roll=%.60s,rise=%.60s,stand=%.60s] active=%s",
                  a.name.c_str(), rise.name.c_str(), stand.name.c_str(), stage_name(stage_));
    std::snprintf(policy_hash_, sizeof(policy_hash_), "%.32s+%.32s+%.32s", a.content_hash.c_str(),
                  rise.content_hash.c_str(), stand.content_hash.c_str());
  } else {
    std::snprintf(policy_name_, sizeof(policy_name_), "%s", a.name.c_str());
    std::snprintf(policy_hash_, sizeof(policy_hash_), "%s", a.content_hash.c_str());
  }
}

void Controller::publish_status(double now_s) {
  const Mode mode = supervisor_.mode();
  status_.utime = static_cast<int64_t>(now_s * kSToUs);
  status_.mode = static_cast<int8_t>(mode);
  assign_bounded(status_.mode_name, mode_name(mode));
  format_policy_identity();
  assign_bounded(status_.policy_name, policy_name_);
  assign_bounded(status_.policy_hash, policy_hash_);
  assign_bounded(status_.clock, clock_name(opt_.clock));
  status_.ticks = ticks_;
  status_.policy_ticks = policy_ticks_;
  status_.overruns = task_.overruns();
  status_.seq_gaps_imu = supervisor_.imu_seq().gaps();
  status_.seq_gaps_joint = supervisor_.joint_seq().gaps();
  status_.seq_reordered_imu = supervisor_.imu_seq().reordered();
  status_.seq_reordered_joint = supervisor_.joint_seq().reordered();
  status_.decode_errors = transport_.decode_errors + link_->rejected_samples();  // and samples the link refused whole
  status_.commands_dropped = transport_.commands_dropped;
  status_.sends_dropped = static_cast<int64_t>(transport_.send_dropped());
  TimingStats& late = task_.lateness();
  TimingStats& comp = task_.compute();
  status_.lateness_us_last = static_cast<float>(late.last());
  status_.lateness_us_mean = static_cast<float>(late.mean());
  status_.lateness_us_p99 = static_cast<float>(late.p99());
  status_.lateness_us_max = static_cast<float>(late.max());
  status_.compute_us_last = static_cast<float>(comp.last());
  status_.compute_us_mean = static_cast<float>(comp.mean());
  status_.compute_us_p99 = static_cast<float>(comp.p99());
  status_.compute_us_max = static_cast<float>(comp.max());
  auto age_ms = [now_s](bool have, double t) { return have ? static_cast<float>((now_s - t) * kSToMs) : -1.0f; };
  status_.imu_age_ms = age_ms(transport_.imu.have, transport_.imu.stamp_s);
  status_.joint_age_ms = age_ms(transport_.joint.have, transport_.joint.stamp_s);
  status_.joystick_age_ms = age_ms(transport_.joystick.have, transport_.joystick.stamp_s);
  status_.fault_bits = supervisor_.fault_bits();
  assign_bounded(status_.last_fault, supervisor_.last_fault());
  auth_.report(status_);
  report_state_source();
  if (message_changed_.load()) {
    std::unique_lock<std::mutex> lock(reload_mutex_, std::try_to_lock);
    if (lock.owns_lock()) {
      std::snprintf(reload_info_, sizeof(reload_info_), "%s", reload_message_.c_str());
      message_changed_.store(false);
    }
  }
  char composite_info[160] = {0};
  if (composite())
    std::snprintf(composite_info, sizeof(composite_info),
                  "composite: waist %.3f m from T1_SIM_STATUS (privileged sim "
                  "signal), getup below %.2f m, active %s, switches %lld | ",
                  transport_.sim_status.msg.waist_height, kGetupSwitchWaistHeightM, member_name(member_),
                  static_cast<long long>(member_switches_));
  else if (chain())
    std::snprintf(composite_info, sizeof(composite_info),
                  "chain: trunk %.3f m from T1_SIM_STATUS (privileged sim "
                  "signal), rise hands over at |u - e_z| < %.2f, active %s, switches %lld | ",
                  transport_.sim_status.msg.trunk_height, handover_up_error_, stage_name(stage_),
                  static_cast<long long>(member_switches_));
  // Who may command next to the mode: "commands unauthenticated" on a bench runtime, the last refusal.
  const char* bench = auth_.mode() == AuthMode::kUnauthenticated ? " | commands unauthenticated" : "";
  const char* refusal = auth_.last_refusal();
  char info
      [kStringReserve + 880 +
       2 * sizeof(
               state_source_)];  // composite (160) + supervisor (160) + auth (230) + reload message + the link's rejection (160)
  const char* link_info = link_->last_rejection();
  std::snprintf(info, sizeof(info), "%s%s%s%s%s%s%s%s%s%s%s", composite_info, supervisor_.last_info(), bench,
                refusal[0] ? " | " : "", refusal, reload_info_[0] ? " | " : "", reload_info_, link_info[0] ? " | " : "",
                link_info, state_source_[0] ? " | " : "", state_source_);
  assign_bounded(status_.info, info);
  transport_.publish(t1::CH_CONTROLLER_STATUS, status_);
  post_live_line();  // the live line, and the no-state notice even when quiet
}

// controller_status_t.state_*: whose state, what was refused, and a named warning while refusals stream in
// (frames refused since the previous status: kStateRefused), or a second source (R12) was seen.
void Controller::report_state_source() {
  state_auth_.report_state(status_);
  const int64_t refused = state_auth_.refused_total();
  const int64_t second = supervisor_.second_source_frames() + link_->second_writer_samples();
  const int64_t new_refused = refused - reported_state_refused_, new_second = second - reported_second_source_;
  reported_state_refused_ = refused;
  reported_second_source_ = second;
  const bool warning = new_refused > 0 || new_second > 0;
  if (warning) status_.fault_bits |= fault_bit::kStateRefused;
  const char* refusal = state_auth_.last_refusal();
  const char* link_other = link_->second_writer();
  if (warning || !state_source_[0])
    std::snprintf(state_source_, sizeof(state_source_),
                  "%s%lld state frames refused, %lld of a second source%s%s%s%s%s%s", warning ? "REFUSING STATE: " : "",
                  static_cast<long long>(new_refused), static_cast<long long>(new_second), refusal[0] ? "; last: " : "",
                  refusal, supervisor_.second_source()[0] ? "; " : "", supervisor_.second_source(),
                  link_other[0] ? "; " : "", link_other);
  if (!warning && refused == 0 && second == 0) state_source_[0] = '\0';
  assign_bounded(status_.state_source, state_source_);
}

}  // namespace t1rt
