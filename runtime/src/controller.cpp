#include "t1rt/controller.hpp"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "t1_contract.hpp"

namespace t1rt {

namespace {
std::atomic<bool> g_sighup{false};
constexpr std::size_t kStringReserve = Controller::kStatusStringReserve;
constexpr std::size_t kObsReserve = 1024;           // observation_t vectors: largest obs size without reallocation
constexpr int64_t kLiveLinePeriodNs = 200'000'000;  // terminal status line at 5 Hz
// No fresh state for this long: say what the runtime waits for, then again every kNoStateRepeatNs.
constexpr int64_t kNoStateNoticeNs = 1'000'000'000;
constexpr int64_t kNoStateRepeatNs = 10'000'000'000;
constexpr float kNsToS = 1e-9f;
constexpr double kSToUs = 1e6, kSToMs = 1e3;
constexpr const char* kApprovalsFileName = "approvals";  // the approvals file's default name in the policy folder
}  // namespace

PolicyStore make_policy_store(const ControllerOptions& o) {
  // a chain's folder holds its members: it is their policy folder
  const std::string own =
      is_chain_folder(o.policy_path) ? o.policy_path : std::filesystem::path(o.policy_path).parent_path().string();
  std::string dir = o.policy_dir.empty() ? own : o.policy_dir;
  if (dir.empty()) dir = ".";
  const std::string approvals = o.approvals_path.empty() ? dir + "/" + kApprovalsFileName : o.approvals_path;
  return PolicyStore(dir, o.auth == AuthMode::kSigned ? o.keys : nullptr, approvals);
}

Controller::Controller(const ControllerOptions& options, std::unique_ptr<PolicyEngine> initial,
                       std::unique_ptr<PolicyEngine> upright)
    : opt_(options), supervisor_(options.safety), store_(make_policy_store(options)), engine_(std::move(initial)) {
  active_ = engine_.get();
  if (upright) {
    check_composite_pair(engine_->artifact(), upright->artifact());  // throws before any thread
    rule_ = SwitchRule::kWaist;
    others_.push_back(std::move(upright));
    members_ = {engine_.get(), others_[0].get()};
    // PREPARE ramps to the upright member's pose (a stand); it runs first unless the waist is low.
    active_ = others_[0].get();
  }
  init_common();
}

Controller::Controller(const ControllerOptions& options, std::array<std::unique_ptr<PolicyEngine>, kChainStages> chain,
                       float handover_up_error)
    : opt_(options),
      supervisor_(options.safety),
      store_(make_policy_store(options)),
      engine_(std::move(chain[0])),
      rule_(SwitchRule::kKeyframe),
      handover_up_error_(handover_up_error) {
  members_ = {engine_.get()};
  for (std::size_t i = 1; i < kChainStages; ++i) {
    check_composite_pair(engine_->artifact(), chain[i]->artifact());  // one gain set: throws before any thread
    members_.push_back(chain[i].get());
    others_.push_back(std::move(chain[i]));
  }
  // PREPARE ramps to the stand's pose; the Trunk's height picks the first stage once POLICY starts.
  active_ = members_[static_cast<std::size_t>(ChainStage::kStand)];
  init_common();
}

void Controller::init_common() {
  supervisor_.set_autostart(opt_.autostart);  // the ladder and the operator's precedence: safety rule R1
  current_path_ = opt_.policy_path;
  for (std::string* s :
       {&status_.mode_name, &status_.policy_name, &status_.policy_hash, &status_.clock, &status_.last_fault,
        &status_.info, &status_.command_auth, &status_.state_auth, &status_.state_source})
    s->reserve(kStringReserve);
  obs_msg_.raw.reserve(kObsReserve);
  obs_msg_.normalized.reserve(kObsReserve);
  action_msg_.action.reserve(kJoints);
  reload_message_.reserve(kStringReserve);
  reload_thread_ = std::thread(&Controller::reload_worker, this);
}

Controller::~Controller() {
  {
    std::lock_guard<std::mutex> lock(reload_mutex_);
    worker_exit_ = true;
  }
  reload_cv_.notify_all();
  reload_thread_.join();
}

bool Controller::open(std::string* error) {
  if (!auth_.open(opt_.auth, opt_.keys, opt_.auth_config, error)) return false;
  // Whose state: the robot key's frames only (--robot-key), else every frame (rule R12 still watches).
  const bool robot_key = opt_.robot_keys != nullptr;
  if (!state_auth_.open(robot_key ? AuthMode::kSigned : AuthMode::kUnauthenticated, opt_.robot_keys, opt_.auth_config,
                        error))
    return false;
  char describe[96];
  if (robot_key) std::snprintf(describe, sizeof(describe), "signed (robot key, %zu senders)", opt_.robot_keys->size());
  else std::snprintf(describe, sizeof(describe), "unauthenticated (no --robot-key)");
  state_auth_.set_description(describe);
  if (!transport_.open(opt_.lcm_url, opt_.clock, &supervisor_, &auth_, error, switched(), state_on_lcm(opt_.robot_link),
                       &state_auth_))
    return false;
  link_ = open_robot_link(opt_.robot_link, opt_.dds_domain_id, opt_.clock, &supervisor_, &transport_, error,
                          opt_.safety.restart_quiet_s);
  return link_ != nullptr;
}

void Controller::publish_command() { link_->publish(command_); }

void Controller::send_exit_damping() {
  if (!transport_.joint.have) return;  // never commanded anything: nothing to release
  supervisor_.estop();                 // DAMPING (a latched FAULT is damping already)
  const double now_s = opt_.clock == ClockMode::kLockstep ? transport_.joint.stamp_s : monotonic_s();
  const StateView s = state_view(now_s);
  supervisor_.begin_tick(s, active_->artifact());
  supervisor_.finish_tick(s, active_->artifact(), active_->q_target(), command_);
  command_.utime = static_cast<int64_t>(now_s * kSToUs);
  command_.seq = cmd_seq_++;
  command_.state_seq = transport_.joint.msg.seq;
  publish_command();
}

void Controller::notify_sighup() { g_sighup.store(true); }

void Controller::request_reload(const std::string& path) {
  {
    std::lock_guard<std::mutex> lock(reload_mutex_);
    reload_path_ = path;
    reload_requested_ = true;
  }
  reload_cv_.notify_all();
}

std::string Controller::reload_message() {
  std::lock_guard<std::mutex> lock(reload_mutex_);
  return reload_message_;
}

void Controller::reload_worker() {
  std::unique_lock<std::mutex> lock(reload_mutex_);
  for (;;) {
    reload_cv_.wait(lock, [this] { return reload_requested_ || worker_exit_ || retired_; });
    if (worker_exit_) return;
    retired_.reset();  // the old engine is freed here, never on the loop thread
    if (!reload_requested_) continue;
    reload_requested_ = false;
    const std::string name = reload_path_;  // empty: SIGHUP, the current file again
    const std::string path = name.empty() ? current_path_ : name;
    lock.unlock();
    std::unique_ptr<PolicyEngine> engine;
    std::string message;
    if (switched()) {
      // A reload would have to swap one member and re-check the gains against the others while it runs;
      // switched runs are evaluation runs, so they are restarted with all their files instead.
      message = std::string("reload REJECTED, old policies kept: hot reload is not supported in ") +
                (chain() ? "chain" : "composite") + " mode";
    } else try {
        // load_policy: a name inside the policy folder, approved content only; SIGHUP (a local signal): the
        // current file, approved again when the runtime has a key (the file may have been replaced).
        engine = std::make_unique<PolicyEngine>(!name.empty()              ? store_.load_name(name)
                                                : store_.checks_approval() ? store_.load_path(path)
                                                                           : load_artifact(path));
        message = "reload ok: " + path + " (" + engine->artifact().name + ", " +
                  engine->artifact().content_hash.substr(0, 12) + ")";
      } catch (const PolicyRefused& e) {
        message = std::string("reload REJECTED, old policy kept: ") + e.what();
      } catch (const std::exception& e) {
        message = "reload REJECTED, old policy kept: " + path + ": " + e.what();
      }
    lock.lock();
    reload_message_ = message.substr(0, kStringReserve - 1);
    if (!engine) {
      message_changed_.store(true);
      continue;
    }                                         // "reload ok" shows once the loop adopts it
    current_path_ = engine->artifact().path;  // the resolved file
    ready_ = std::move(engine);
    ready_flag_.store(true);
  }
}

void Controller::adopt_ready_policy() {
  if (!ready_flag_.load()) return;
  std::unique_lock<std::mutex> lock(reload_mutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;  // never block the tick: try again at the next policy tick
  std::swap(engine_, ready_);
  active_ = engine_.get();  // single-policy mode only (a switched mode never has a ready policy)
  retired_ = std::move(ready_);
  ready_flag_.store(false);
  message_changed_.store(true);
  engine_->reset();
  lock.unlock();
  reload_cv_.notify_all();
}

StateView Controller::state_view(double now_s) const { return transport_.state_view(now_s, switched()); }

void Controller::handle_commands() {
  for (std::size_t i = 0; i < transport_.command_count; ++i) {
    const t1::runtime_cmd_t& c = transport_.commands[i];
    Mode mode;
    if (c.verb == "estop") supervisor_.estop();
    else if (c.verb == "reset") supervisor_.reset();
    else if (c.verb == "load_policy") request_reload(c.argument);
    else if (c.verb == "set_mode" && parse_mode(c.argument.c_str(), &mode)) supervisor_.request_mode(mode);
    else
      std::fprintf(stderr, "t1-runtime: ignored runtime_cmd_t verb '%s' argument '%s'\n", c.verb.c_str(),
                   c.argument.c_str());
  }
  transport_.command_count = 0;
  if (transport_.estop_pending) supervisor_.estop();  // after the queue: estop wins in its tick (rule R2)
  transport_.estop_pending = false;
}

void Controller::tick(double now_s) {
  if (g_sighup.exchange(false)) request_reload("");
  handle_commands();
  const StateView s = state_view(now_s);
  const auto& js = transport_.joystick;
  supervisor_.gate_joystick(now_s, js.have, js.stamp_s, &js.msg.vx, active_->artifact().command_ranges, command_vel_);
  const bool may_run_policy = supervisor_.begin_tick(s, active_->artifact());
  bool policy_ran = false;
  if (supervisor_.entered_policy()) {
    engine_->reset();
    for (auto& other : others_) other->reset();
    stage_ = ChainStage::kStart;
    policy_phase_ = 0;
  }
  if (may_run_policy && policy_phase_ % kPolicyDecimation == 0) {
    adopt_ready_policy();
    if (switched()) select_member(s);
    const auto result = active_->step(s.quat, s.gyro, command_vel_, s.q, s.dq);
    if (switched() && result == PolicyEngine::Result::kOk)
      for (PolicyEngine* idle : members_)
        if (idle != active_) idle->follow(active_->q_target(), command_vel_);
    if (result == PolicyEngine::Result::kNonFiniteObs)
      supervisor_.fault(fault_bit::kNonFiniteObs, "non-finite observation");
    if (result == PolicyEngine::Result::kNonFiniteAction)
      supervisor_.fault(fault_bit::kNonFiniteAction, "non-finite action");
    ++policy_ticks_;
    policy_ran = true;
  }
  if (may_run_policy) ++policy_phase_;
  else if (supervisor_.mode() != Mode::kPolicy) adopt_ready_policy();  // no policy running: swap at once

  supervisor_.finish_tick(s, active_->artifact(), active_->q_target(), command_);
  command_.utime = static_cast<int64_t>(now_s * kSToUs);
  command_.seq = cmd_seq_++;
  command_.state_seq = transport_.joint.have ? transport_.joint.msg.seq : -1;
  publish_command();
  ++ticks_;
  if (policy_ran) publish_policy_telemetry(now_s);  // after the command: the robot never waits for observers
  // The next tick runs the policy: bring its weights into cache now, while the robot has its command.
  if (may_run_policy && policy_phase_ % kPolicyDecimation == 0) active_->warm_cache();
  if (ticks_ % kStatusEveryTicks == 0) publish_status(now_s);
}

void Controller::publish_policy_telemetry(double now_s) {
  const int64_t utime = static_cast<int64_t>(now_s * kSToUs);
  obs_msg_.utime = action_msg_.utime = utime;
  obs_msg_.policy_tick = action_msg_.policy_tick = policy_ticks_;
  const auto& raw = active_->obs_raw();
  obs_msg_.size = static_cast<int32_t>(raw.size());
  obs_msg_.raw.assign(raw.data(), raw.data() + raw.size());
  obs_msg_.normalized.assign(active_->obs_normalized().data(), active_->obs_normalized().data() + raw.size());
  action_msg_.size = static_cast<int32_t>(kJoints);
  action_msg_.action.assign(active_->action().begin(), active_->action().end());
  std::copy(active_->q_target().begin(), active_->q_target().end(), action_msg_.q_target);
  transport_.publish(t1::CH_OBS, obs_msg_);
  transport_.publish(t1::CH_ACTION, action_msg_);
}

void Controller::select_member(const StateView& s) {
  PolicyEngine* next;
  if (rule_ == SwitchRule::kWaist) {
    member_ = t1rt::select_member(s.waist_height_m);
    next = members_[static_cast<std::size_t>(member_)];
  } else {
    stage_ = next_stage(stage_, trunk_readings(s.quat, s.gyro, s.trunk_height_m), handover_up_error_);
    next = members_[static_cast<std::size_t>(stage_)];
  }
  if (next != active_) ++member_switches_;
  active_ = next;
}

void Controller::post_live_line() {
  LiveLine line{};
  std::snprintf(line.mode, sizeof(line.mode), "%s", status_.mode_name.c_str());
  std::snprintf(line.last_fault, sizeof(line.last_fault), "%s", status_.last_fault.c_str());
  if (composite())  // switched modes: say they run on a privileged sim signal, and which member acts
    std::snprintf(line.composite, sizeof(line.composite), "COMPOSITE(sim waist %.2f m -> %-7s) ",
                  transport_.sim_status.msg.waist_height, member_name(member_));
  else if (chain())
    std::snprintf(line.composite, sizeof(line.composite), "CHAIN(sim trunk %.2f m -> %-5s) ",
                  transport_.sim_status.msg.trunk_height, stage_name(stage_));
  line.unauthenticated = auth_.mode() == AuthMode::kUnauthenticated;
  line.ticks = ticks_;
  line.policy_ticks = policy_ticks_;
  line.overruns = task_.overruns();
  line.lateness_p99_us = status_.lateness_us_p99;
  line.compute_p99_us = status_.compute_us_p99;
  line.imu_age_ms = status_.imu_age_ms;
  line.joint_age_ms = status_.joint_age_ms;
  live_line_.write(line);
}

void Controller::live_line_worker() {
  // What the loop waits for, named once it has waited kNoStateNoticeNs (no state yet, or none since then).
  const std::string awaited =
      state_on_lcm(opt_.robot_link)
          ? std::string(t1::CH_IMU) + " / " + t1::CH_JOINT_STATE + " on " + opt_.lcm_url
          : std::string(t1::kDdsStateTopic) + " on DDS domain " + std::to_string(opt_.dds_domain_id);
  const auto fresh = [](float age_ms) { return age_ms >= 0.0f && age_ms < kNoStateNoticeNs * 1e-6f; };
  LiveLine line{};
  int64_t last_fresh_ns = monotonic_ns(), next_notice_ns = 0;
  while (!stop_.load()) {
    std::this_thread::sleep_for(std::chrono::nanoseconds(kLiveLinePeriodNs));
    const int64_t now = monotonic_ns();
    if (live_line_.read(&line)) {
      if (fresh(line.imu_age_ms) && fresh(line.joint_age_ms)) last_fresh_ns = now, next_notice_ns = 0;
      if (!opt_.quiet)
        std::fprintf(stderr,
                     "\r%s%s%-7s ticks %lld pol %lld | late p99 %6.1f us | comp p99 %6.1f us | age imu %5.1f joint "
                     "%5.1f ms | ovr %lld | %.60s   ",
                     line.unauthenticated ? "UNAUTHENTICATED " : "", line.composite, line.mode,
                     static_cast<long long>(line.ticks), static_cast<long long>(line.policy_ticks),
                     line.lateness_p99_us, line.compute_p99_us, line.imu_age_ms, line.joint_age_ms,
                     static_cast<long long>(line.overruns), line.last_fault);
    }
    if (now - last_fresh_ns >= kNoStateNoticeNs && now >= next_notice_ns) {
      std::fprintf(stderr, "%st1-runtime: no %s for %.0f s: is the robot or the sim running?\n", opt_.quiet ? "" : "\n",
                   awaited.c_str(), static_cast<float>(now - last_fresh_ns) * kNsToS);
      next_notice_ns = now + kNoStateRepeatNs;
    }
  }
}

bool Controller::step_lockstep(int timeout_ms) {
  const int64_t start = monotonic_ns();
  while (!transport_.new_joint_state) {
    const int64_t left_ms = timeout_ms - (monotonic_ns() - start) / 1'000'000;
    if (left_ms <= 0) return false;
    const int got = link_->wait(static_cast<int>(left_ms));
    if (got < 0) return false;
  }
  transport_.drain();  // the IMU or commands sent alongside this state
  transport_.new_joint_state = false;
  const int64_t t0 = monotonic_ns();
  tick(transport_.joint.stamp_s);  // sim time of the state being answered
  task_.compute().add(static_cast<double>(monotonic_ns() - t0) / 1000.0);
  return true;
}

void Controller::step_realtime() {
  const int64_t wake_ns = task_.wait_next();
  transport_.drain();
  link_->drain();
  tick(ns_to_s(wake_ns));
  task_.end_compute();
}

void Controller::run() {
  live_line_thread_ = std::thread(&Controller::live_line_worker, this);
  const int64_t start = monotonic_ns();
  const int64_t end = opt_.duration_s > 0 ? start + static_cast<int64_t>(opt_.duration_s * 1e9) : INT64_MAX;
  task_.start();
  while (!stop_.load() && monotonic_ns() < end) {
    if (opt_.clock == ClockMode::kLockstep) step_lockstep(opt_.lockstep_wait_ms);
    else step_realtime();
  }
  send_exit_damping();
  stop_.store(true);
  if (live_line_thread_.joinable()) live_line_thread_.join();
  if (!opt_.quiet) std::fprintf(stderr, "\n");
}

}  // namespace t1rt
