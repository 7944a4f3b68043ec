// The controller: one tick function shared by the realtime and the lockstep clock, the policy hot-reload
// worker, and telemetry. Everything the tick touches is allocated before the loop starts.
#pragma once
#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "t1/action_t.hpp"
#include "t1/controller_status_t.hpp"
#include "t1/joint_command_t.hpp"
#include "t1/observation_t.hpp"
#include "t1rt/command_auth.hpp"
#include "t1rt/composite.hpp"
#include "t1rt/handover.hpp"
#include "t1rt/keyframe_chain.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/policy.hpp"
#include "t1rt/policy_store.hpp"
#include "t1rt/robot_link.hpp"
#include "t1rt/safety.hpp"
#include "t1rt/transport.hpp"

namespace t1rt {

struct ControllerOptions {
  std::string policy_path;          // the single policy; in composite mode the getup member; a chain's folder
  std::string upright_policy_path;  // non-empty: composite mode (composite.hpp), the upright member
  std::string lcm_url;              // resolved (resolve_lcm_url)
  RobotLinkKind robot_link = RobotLinkKind::kLcm;  // which link faces the robot (robot_link.hpp)
  int dds_domain_id = 0;                           // --transport dds: the robot's DDS domain (contract.json)
  ClockMode clock = ClockMode::kRealtime;
  bool autostart = false;      // PASSIVE -> DAMPING -> PREPARE -> POLICY without operator commands
  bool quiet = false;          // no live status line
  double duration_s = 0.0;     // wall-clock run time; <= 0: until SIGINT/SIGTERM
  int lockstep_wait_ms = 100;  // one handleTimeout slice while waiting for a state in lockstep
  SafetyConfig safety;
  // Who may command (command_auth.hpp; safety rule R11). kSigned: keys is the --key file.
  AuthMode auth = AuthMode::kEstopOnly;
  std::shared_ptr<const KeyRing> keys;
  // Whose state (--robot-key FILE): only imu_t / joint_state_t signed by a sender of robot_keys are taken;
  // null: every frame (a bench), safety rule R12 still tells a second sequence stream apart.
  std::shared_ptr<const KeyRing> robot_keys;
  AuthConfig auth_config;
  std::string policy_dir;      // load_policy's folder; empty: the folder of policy_path
  std::string approvals_path;  // with keys: the approvals file; empty: policy_dir/approvals
};

// The policy folder of these options (policy_store.hpp): approvals checked when they have keys. Throws
// PolicyRefused when the folder does not exist.
PolicyStore make_policy_store(const ControllerOptions& options);

class Controller {
 public:
  static constexpr std::size_t kStatusStringReserve =
      512;  // status strings reuse this capacity: no per-tick allocation
  // upright_policy non-null: composite mode, initial_policy is the getup member. Throws ArtifactError
  // when the pair does not share one gain set (check_composite_pair).
  Controller(const ControllerOptions& options, std::unique_ptr<PolicyEngine> initial_policy,
             std::unique_ptr<PolicyEngine> upright_policy = nullptr);
  // Chain mode (keyframe_chain.hpp): the members in ChainStage order, the rise → stand hand-over's upright bound.
  // Throws ArtifactError when they do not share one gain set.
  Controller(const ControllerOptions& options, std::array<std::unique_ptr<PolicyEngine>, kChainStages> chain,
             float handover_up_error);
  ~Controller();

  bool open(std::string* error);  // the LCM transport and the robot link; false on failure
  // The single code path: one control tick on the newest state at time now_s (see StateView for clocks).
  void tick(double now_s);
  bool step_lockstep(int timeout_ms);  // waits for a joint_state_t, then ticks; false on timeout
  void step_realtime();                // sleeps to the next deadline, drains LCM, ticks
  void run();                          // until stop() or duration, then send_exit_damping()
  void send_exit_damping();            // one DAMPING command (kp 0, kd safe) to the robot: leave it limp, not stiff
  void stop() { stop_.store(true); }

  // Hot reload (runtime_cmd_t load_policy, SIGHUP): validated on the worker thread, swapped at a policy tick.
  void request_reload(const std::string& path);  // empty path = reload the current file
  static void notify_sighup();                   // async-signal-safe

  Supervisor& supervisor() { return supervisor_; }
  PolicyEngine& policy() { return *engine_; }         // composite mode: the getup member; chain: the roll
  PolicyEngine& active_policy() { return *active_; }  // the one whose targets are commanded
  bool composite() const { return rule_ == SwitchRule::kWaist; }
  bool chain() const { return rule_ == SwitchRule::kKeyframe; }
  bool switched() const { return rule_ != SwitchRule::kNone; }  // on a privileged sim signal (T1_SIM_STATUS)
  CompositeMember member() const { return member_; }
  ChainStage chain_stage() const { return stage_; }
  int64_t member_switches() const { return member_switches_; }
  PeriodicTask& task() { return task_; }
  LcmTransport& transport() { return transport_; }
  int64_t ticks() const { return ticks_; }
  int64_t policy_ticks() const { return policy_ticks_; }
  const t1::joint_command_t& last_command() const { return command_; }
  std::string reload_message();  // last reload result (copy, for tests)
  const CommandAuth& auth() const { return auth_; }
  const CommandAuth& state_auth() const { return state_auth_; }
  const t1::controller_status_t& status() const { return status_; }
  const PolicyStore& policy_store() const { return store_; }

 private:
  void handle_commands();
  void publish_command();
  void publish_policy_telemetry(double now_s);  // T1_OBS / T1_ACTION of this policy tick, after its command
  void adopt_ready_policy();
  void publish_status(double now_s);
  void report_state_source();
  void post_live_line();    // the loop's side: a snapshot into live_line_
  void live_line_worker();  // its own thread: the newest snapshot at 5 Hz (not --quiet); no state for 1 s: says so
  void reload_worker();
  StateView state_view(double now_s) const;
  void select_member(const StateView& s);
  void init_common();  // what both constructors do last: reserves, the reload worker
  void format_policy_identity();

  ControllerOptions opt_;
  Supervisor supervisor_;
  CommandAuth auth_;
  CommandAuth state_auth_;  // the robot's state frames (ControllerOptions::robot_keys)
  int64_t reported_state_refused_ = 0, reported_second_source_ = 0;  // as of the previous status
  char state_source_[512] = {0};
  PolicyStore store_;
  LcmTransport transport_;
  std::unique_ptr<RobotLink> link_;  // the robot's state in, joint commands out (LCM or DDS)
  PeriodicTask task_;
  std::unique_ptr<PolicyEngine> engine_;
  // Switched modes (never reloaded): the members after engine_ (composite: the upright; chain: rise, stand), all
  // members in their rule's order (composite: getup, upright; chain: roll, rise, stand), which rule switches them.
  enum class SwitchRule { kNone, kWaist, kKeyframe };
  std::vector<std::unique_ptr<PolicyEngine>> others_;
  std::vector<PolicyEngine*> members_;
  SwitchRule rule_ = SwitchRule::kNone;
  PolicyEngine* active_ = nullptr;  // one of members_, or engine_
  CompositeMember member_ = CompositeMember::kUpright;
  ChainStage stage_ = ChainStage::kStart;
  float handover_up_error_ = t1::kKneelGateUpError;
  int64_t member_switches_ = 0;
  char policy_name_[256] = {0}, policy_hash_[160] = {0};  // status strings, formatted off the hot path
  t1::joint_command_t command_{};
  t1::observation_t obs_msg_{};
  t1::action_t action_msg_{};
  t1::controller_status_t status_{};
  float command_vel_[3] = {0, 0, 0};  // gated joystick command [m/s, m/s, rad/s]
  int64_t ticks_ = 0, policy_ticks_ = 0, policy_phase_ = 0, cmd_seq_ = 0;
  std::atomic<bool> stop_{false};

  // The live status line leaves the loop through a lock-free hand-over: stderr may block, the loop may not.
  struct LiveLine {
    char mode[16];
    char last_fault[64];
    char composite[64];    // empty unless a switched mode
    bool unauthenticated;  // --unauthenticated: the line says so
    int64_t ticks, policy_ticks, overruns;
    float lateness_p99_us, compute_p99_us, imu_age_ms, joint_age_ms;
  };
  Latest<LiveLine> live_line_;
  std::thread live_line_thread_;

  // reload worker state (guarded by reload_mutex_; reload_path_ is a load_policy name, current_path_ a path)
  std::mutex reload_mutex_;
  std::condition_variable reload_cv_;
  std::thread reload_thread_;
  bool reload_requested_ = false, worker_exit_ = false;
  std::string reload_path_, current_path_, reload_message_;
  std::unique_ptr<PolicyEngine> ready_, retired_;
  std::atomic<bool> ready_flag_{false};
  std::atomic<bool> message_changed_{false};
  char reload_info_[512] = {0};  // loop-side copy of the last reload result
};

}  // namespace t1rt
