// Safety supervisor: modes, state checks and command clamps. The rules live in ONE file,
// src/safety_supervisor.cpp; nothing else in the runtime may change a joint command.
//
// Modes and transitions (start-up mode PASSIVE):
//   PASSIVE  --set_mode damping | autostart-->  DAMPING  --set_mode prepare | autostart-->  PREPARE
//   PREPARE  --(ramp finished) set_mode policy | autostart-->  POLICY
//   any but FAULT --set_mode passive/damping--> that mode;  estop --> DAMPING (FAULT stays FAULT)
//   any --fault--> FAULT (latched damping);  FAULT --reset--> DAMPING (only way out)
// Operator precedence: estop and set_mode passive|damping suspend autostart until the operator's next
// reset or set_mode prepare|policy. The rules, implemented in src/safety_supervisor.cpp:
//
// Rules of the link and the artifact (each has a test named in runtime/README.md):
//  R1 Operator precedence. estop and set_mode passive|damping set an operator hold: autostart makes no
//     request while it is set, so the operator's DAMPING/PASSIVE stands. Only the operator releases it:
//     reset, or set_mode prepare|policy. (Autostart lives here, not in the controller, for that reason.)
//  R2 estop is never dropped: the transport keeps it outside the bounded command queue and the controller
//     applies it after the queued commands of the same tick (estop wins over any request in that tick).
//  R3 State frames: decoded into scratch and committed only when the decode succeeds (LcmTransport);
//     a frame whose seq is not newer than the newest one is rejected and counted as reordered; gaps
//     count seq numbers never received (a late frame that fills a counted gap takes it back).
//     A frame more than SeqTracker::kWindowFrames older than the newest is a publisher restart: accepted.
//  R4 Motor status: WATCHDOG, POWER_ON, DAMPING (the motor is not following: T1_STATUS_NOT_FOLLOWING),
//     BAD_FRAME and BAD_SENSOR are a FAULT in PREPARE/POLICY; in DAMPING a warning that blocks PREPARE.
//  R5 Joystick: non-finite or stale -> zero; else each axis clamped to the artifact's command_ranges.
//  R6 Final q_des per joint, when the limits conflict, in this priority (clamp_targets):
//       1. rate: |q_des - last q_des| <= max_target_step_rad, always (a command never jumps);
//       2. torque: |kp (q_des - q) - kd dq| <= torque limit, as far as reachable under 1;
//       3. range: inside joint_range_fraction of the joint range, as far as reachable under 1 and 2.
//     Each step picks the point of the allowed interval nearest to the wanted target, so with q outside
//     the range the target moves toward the range at full allowed torque and never away from it.
//  R7 A fault also rewrites the status info ("FAULT: <reason>"), so the info never names a stale mode.
// Motor health rules, counted once per joint state in every mode; FAULT naming the motor in
// PREPARE/POLICY, in PASSIVE/DAMPING a warning that blocks PREPARE (as R4). Figures: tools/motor_watchdog_figures.py.
//  R8 Silent motor: > kMotorSilentMaxCycles (10) consecutive states with NO_REPLY (no reply that bus cycle;
//     on DDS MotorState_.lost changed). At 5 % random loss a run of 11 has odds 0.05^11 = 5e-15 per
//     motor-cycle, one false trip in ~600 years of 23 motors at 500 Hz (longest run measured: 3). A dead
//     motor trips 22 ms after its last reply, before its own 50 ms watchdog.
//  R9 Frozen encoder: q bit-identical on consecutive replies under a PD torque above
//     frozen_encoder_torque_nm, more than kFrozenEncoderStopMarginRad inside the range, while the IMU's
//     low-passed angular rate says the body turns and the motors' low-passed speed says the limbs move, for
//     more than kFrozenEncoderMaxCycles replies (80 ms). Missing replies neither advance nor reset it.
//  R10 Impossible reading: a reply past its range by more than kImpossibleRangeMarginRad, or a step
//     from the motor's previous reply faster than kImpossibleSpeedFactor x its class's v_max; at once.
//     Why these signals and values, the latencies and the false-alarm argument: t1rt/safety.hpp.
//  R11 Operator authority (MAVLink 2 signing; an emergency stop works from any station, a reset needs the
//     authority to run): estop is obeyed from any sender, signed or not; every other runtime_cmd_t (reset,
//     set_mode of any mode, load_policy) and the joystick only when authorised: signed by a key of the
//     runtime's key file with a fresh timestamp (t1rt/command_auth.hpp), or the runtime was started
//     --unauthenticated. So after anyone's estop only the key holder releases R1's hold or leaves
//     FAULT/DAMPING for PREPARE or POLICY. A refused message changes nothing and is counted by reason.
//  R12 One state source. With --robot-key only the robot's signed state frames reach this rule at all
//     (t1rt/command_auth.hpp: the others are refused and counted by reason). On every transport, a state
//     frame R3 would take for a publisher restart (more than SeqTracker::kWindowFrames behind the newest)
//     or a jump of more than max_seq_jump_frames ahead is a second source while the followed stream is
//     alive (a frame of it taken less than restart_quiet_s ago): FAULT "second state source on <channel>",
//     and the frame is refused, never adopted. A real restart stops the old stream first: after
//     restart_quiet_s of silence the new numbering is taken, as R3 says.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

#include "t1/controller_status_t.hpp"
#include "t1/joint_command_t.hpp"
#include "t1_contract.hpp"
#include "t1_motor_protocol.h"
#include "t1rt/artifact.hpp"

namespace t1rt {

enum class Mode : int8_t { kPassive = 0, kDamping = 1, kPrepare = 2, kPolicy = 3, kFault = 4 };
const char* mode_name(Mode mode);
bool parse_mode(const char* text, Mode* mode);  // passive | damping | prepare | policy

// Supervisor fault bits: the low 16 are latched FAULT causes, the high ones are live warnings.
namespace fault_bit {
inline constexpr int32_t kImuStale = 1 << 0;
inline constexpr int32_t kJointStale = 1 << 1;
inline constexpr int32_t kNonFiniteState = 1 << 2;
inline constexpr int32_t kNonFiniteObs = 1 << 3;
inline constexpr int32_t kNonFiniteAction = 1 << 4;
inline constexpr int32_t kMotorFault = 1 << 5;
inline constexpr int32_t kSimStatusStale = 1 << 6;      // composite mode: T1_SIM_STATUS older than fault age
inline constexpr int32_t kNonFiniteSimStatus = 1 << 7;  // composite mode: waist height not finite
inline constexpr int32_t kMotorSilent = 1 << 8;         // rule R8: a motor sent no reply for too many bus cycles
inline constexpr int32_t kEncoderFrozen = 1 << 9;       // rule R9: an encoder read still while the body moved
inline constexpr int32_t kImpossibleReading = 1 << 10;  // rule R10: a reading no joint can produce
inline constexpr int32_t kSecondStateSource = 1 << 11;  // rule R12: a second state stream beside the robot's
inline constexpr int32_t kLatchedMask = t1::controller_status_t::LATCHED_FAULT_MASK;  // the bits above: warnings
inline constexpr int32_t kImuHold = 1 << 16;
inline constexpr int32_t kJointHold = 1 << 17;
inline constexpr int32_t kJoystickStale = 1 << 18;
inline constexpr int32_t kTargetClamped = 1 << 19;
inline constexpr int32_t kRateLimited = 1 << 20;
inline constexpr int32_t kTorqueClamped = 1 << 21;   // includes "torque bound not reachable within the rate limit"
inline constexpr int32_t kMotorWarning = 1 << 22;    // R4 bits, R8 or R9 seen in PASSIVE/DAMPING (blocks PREPARE)
inline constexpr int32_t kMotorOverLimit = 1 << 23;  // OVER_LIMIT: information, never a fault
inline constexpr int32_t kSimStatusHold = 1 << 24;   // composite mode: T1_SIM_STATUS older than hold age
inline constexpr int32_t kStateRefused = 1 << 25;    // state frames refused in the last status period (named
                                                     // in controller_status_t.state_source)
static_assert(kSimStatusHold > kLatchedMask && kNonFiniteSimStatus <= kLatchedMask,
              "fault causes in the latched low bits, warnings above them");
}  // namespace fault_bit

// Motor reply watchdog and encoder plausibility: rules R8, R9, R10 of src/safety_supervisor.cpp; the figures
// come from tools/motor_watchdog_figures.py.
//
// R9, a frozen encoder, is declared only on evidence that the joint moves while its reading does not. A T1
// motor reports q from its encoder; dq (and DDS' ddq) are differentiated from it, and the motor's own PD law
// and soft stop act on it, so a frozen encoder freezes q, zeroes dq and leaves tau_est the honest torque of
// that law on the stuck reading (sim_hil's `frozen` fault does exactly this). Nothing the motor reports
// contradicts a still reading; independent of it are the IMU and the other motors. Evidence, per reply:
// q bit-identical to the motor's previous reply, (a) under the last command's PD torque kp (q_des - q) -
// kd dq above frozen_encoder_torque_nm, (b) more than kFrozenEncoderStopMarginRad inside the joint's range
// (at a stop, the stop explains a still joint under load), (c) while the robot is in motion by two signals
// the frozen encoder does not feed, each low-passed with kBodyMotionTimeConstantS: the IMU's angular rate is
// above kBodyMotionMinRateRadS (the body turns) and the motors' mean |dq| is above kJointMotionMinSpeedRadS
// (the limbs move; a frozen encoder's own dq of 0 only lowers it). Then the loads on every joint change, and
// a joint that keeps its encoder's last code under a large torque and a changing load is not still. (A
// robot swaying after a push turns at 0.1-0.2 rad/s with its limbs still, 0.02-0.07 rad/s: the IMU alone
// held a loaded hip pitch still for 49 replies there.) More than kFrozenEncoderMaxCycles such replies in a
// row: FAULT, 80 ms of coincident evidence (latency from the freeze: see the README's rule table).
// False alarms: a robot at rest (standing, kneeling, lying, leaning on a wall, a test stand replaying one
// pose) has an IMU and motors at rest: standing after a getup the filtered rate stays below 0.015 rad/s
// and the motors' mean speed at their quantisation floor, 0.008 rad/s; walking they are 0.23-0.86 and
// 0.36-1.1 rad/s; a MEMS gyro's bias (< 0.03 rad/s) does not reach 0.1. In motion, over 44 runs of
// standing, walking, getups of three policies, 16 push-test pushes, 5 % drop and 10 ms delay, the longest
// run of replies with this evidence was 17 (a getup), less than half of the 40 that trip. A frozen encoder
// on a joint that does not move is harmless and undetectable, and is not detected.
//
// R10, an impossible reading: a reply past its joint's range by more than kImpossibleRangeMarginRad, or a
// step from the motor's previous reply faster than kImpossibleSpeedFactor x its class's reply range v_max
// (over the bus cycles between the two replies, by joint_state_t.seq) plus kImpossibleJumpQuanta q codes.
// Latency: the first such reply. A state numbered before the motor's last reply (a publisher restart) has
// no previous reading to step from.
inline constexpr int kMotorSilentMaxCycles = 10;             // more consecutive NO_REPLY states: FAULT
inline constexpr float kFrozenEncoderTorqueFraction = 0.5f;  // |PD torque| above this x the motor's limit
inline constexpr float kFrozenEncoderMinTorqueNm = 7.5f;     // and above this [N·m] (above a head's 7 N·m limit)
inline constexpr int kFrozenEncoderMaxCycles = 40;           // ...on a bit-identical encoder for more replies
                                                             // in a row (80 ms of 2 ms bus cycles): FAULT
inline constexpr float kBodyMotionTimeConstantS = 0.05f;     // low-pass of both motion signals below [s]
inline constexpr float kBodyMotionMinRateRadS = 0.1f;        // the IMU's filtered |angular rate| above which
                                                             // the body turns [rad/s]
inline constexpr float kJointMotionMinSpeedRadS = 0.1f;      // the joints' filtered mean |dq| above which
                                                             // the limbs move [rad/s]
inline constexpr float kFrozenEncoderStopMarginRad = 0.02f;  // a reading this close to (or past) a range end is
                                                             // explained by the stop holding the joint [rad]
// R10: a reply no joint produces. Past a range end by more than kImpossibleRangeMarginRad (falls and pushes
// in the model press joints up to 0.26 rad past a stop, 2.6x the soft stop's full-torque reach), or a step
// between two replies faster than kImpossibleSpeedFactor x the class's reply range v_max (t1_motor_protocol.h
// §5; pushes reach 1.74x, on a hip yaw), plus kImpossibleJumpQuanta q codes of rounding.
inline constexpr float kImpossibleRangeMarginRad = 0.5f;
inline constexpr float kImpossibleSpeedFactor = 3.0f;
inline constexpr float kImpossibleJumpQuanta = 2.0f;
// The torque threshold of R9 for motor i [N·m].
inline constexpr float frozen_encoder_torque_nm(float torque_limit_nm) {
  return torque_limit_nm * kFrozenEncoderTorqueFraction > kFrozenEncoderMinTorqueNm
             ? torque_limit_nm * kFrozenEncoderTorqueFraction
             : kFrozenEncoderMinTorqueNm;
}

struct SafetyConfig {
  double hold_age_s = 0.010;        // state older than this: hold the last target
  double fault_age_s = 0.050;       // state older than this: FAULT
  double joystick_stale_s = 0.250;  // joystick older than this: zero command
  // PREPARE's ramp and R6's target shaping: messages/contract.json "supervisor" (training models the same)
  double prepare_duration_s = t1::kPrepareDurationS;  // PREPARE ramp from the current pose to the default pose
  // target rate limit per 2 ms tick (25 rad/s, above every motor's speed)
  float max_target_step_rad = static_cast<float>(t1::kR6MaxTargetSpeedRps * t1::kLoopPeriodS);
  float joint_range_fraction = t1::kR6JointRangeFraction;  // targets clamped to this centred fraction of the range
  double restart_quiet_s = 0.1;       // R12: a new numbering is a restart only after this much silence [s]
  int64_t max_seq_jump_frames = 500;  // R12: a jump further ahead while the stream is alive: a second source
};

// Sequence bookkeeping of one state stream (imu_t or joint_state_t); the rules are in accept().
class SeqTracker {
 public:
  static constexpr int64_t kWindowFrames = 64;  // width of the received-frame mask below
  bool accept(int64_t seq);  // false: not newer than the newest frame (reordered or duplicate): reject
  // Where seq lies from the newest frame: kNew (the first one, or newer), kLate (within the window, not
  // newer), kRestart (further behind: R3's publisher restart). accept() is unchanged by it.
  enum class Step { kNew, kLate, kRestart };
  Step step(int64_t seq) const;
  int64_t newest() const { return newest_; }        // -1: none yet
  int64_t gaps() const { return gaps_; }            // seq numbers never received
  int64_t reordered() const { return reordered_; }  // frames rejected because a newer one came first
 private:
  int64_t newest_ = -1, first_ = -1;  // first_: oldest seq of the current run (no gaps before it)
  uint64_t seen_ = 0;                 // bit i: seq newest_ - i was received (i < 64)
  int64_t gaps_ = 0, reordered_ = 0;
};

// The newest robot state as the loop sees it. Times share one clock: CLOCK_MONOTONIC receive time in
// realtime mode, the messages' own utime (sim time) in lockstep mode.
struct StateView {
  double now_s = 0.0;
  bool have_imu = false;
  double imu_time_s = 0.0;
  const float* quat = nullptr;  // 4
  const float* gyro = nullptr;  // 3
  bool have_joint = false;
  double joint_time_s = 0.0;
  int64_t joint_seq = 0;                  // joint_state_t.seq: bus cycles between two states (R10)
  const float* q = nullptr;               // 23 [rad]
  const float* dq = nullptr;              // 23 [rad/s]
  const int32_t* motor_status = nullptr;  // 23 firmware bits + host NO_REPLY (t1_motor_protocol.h §7)
  // Composite and chain modes only (needs_sim_status): the privileged waist and Trunk heights from
  // T1_SIM_STATUS, which pick the member. Its age follows the same hold / FAULT rules as the IMU and the joint state.
  bool needs_sim_status = false;
  bool have_sim_status = false;
  double sim_status_time_s = 0.0;
  float waist_height_m = 0.0f;  // [m]
  float trunk_height_m = 0.0f;  // [m]
};

class Supervisor {
 public:
  explicit Supervisor(const SafetyConfig& config = SafetyConfig{});
  Mode mode() const { return mode_; }
  // --autostart: walk the mode ladder as soon as each step's preconditions hold, unless the operator holds.
  void set_autostart(bool on) { autostart_ = on; }
  bool operator_hold() const { return operator_hold_; }

  // Rule R11: whether an operator input is obeyed, given whether its sender is authorised.
  enum class OperatorInput { kEstop, kCommand, kJoystick };
  static bool admits(OperatorInput input, bool authorised);

  // Operator inputs (runtime_cmd_t), applied before the tick they arrive in.
  void request_mode(Mode target);  // takes effect in the next begin_tick (needs the state); refusals -> last_info()
  void estop();                    // DAMPING now (FAULT stays latched); holds autostart off
  void reset();                    // FAULT -> DAMPING; releases the operator hold

  // Called by the transport for every decoded (and, with a robot key, verified) state frame, received at
  // now_s (CLOCK_MONOTONIC): false = do not use it (rules R3 and R12).
  bool accept_imu_seq(int64_t seq, double now_s) { return accept_state_seq(imu_source_, imu_seq_, seq, now_s); }
  bool accept_joint_seq(int64_t seq, double now_s) { return accept_state_seq(joint_source_, joint_seq_, seq, now_s); }
  int64_t second_source_frames() const { return second_source_frames_; }  // R12: refused as a second source
  const char* second_source() const { return second_source_.data(); }     // R12: the latest one, named ("")
  const SeqTracker& imu_seq() const { return imu_seq_; }
  const SeqTracker& joint_seq() const { return joint_seq_; }

  // Joystick: zeros it when stale or non-finite, else clamps each axis to the artifact's command range.
  void gate_joystick(double now_s, bool have, double stamp_s, const float* in3,
                     const std::array<std::array<float, 2>, 3>& ranges, float* out3);

  // Phase 1 of a tick: transitions and state checks. Returns true when the policy may run on this state
  // (mode POLICY, state fresh and finite). entered_policy() tells whether POLICY began in this tick.
  bool begin_tick(const StateView& state, const PolicyArtifact& artifact);
  bool entered_policy() const { return entered_policy_; }
  bool prepare_done() const { return prepare_ticks_ >= prepare_total_ticks_; }
  void fault(int32_t bit, const char* reason);

  // Phase 2: the command for this tick (policy_target: the latest policy q_target [rad]).
  void finish_tick(const StateView& state, const PolicyArtifact& artifact, const JointArray& policy_target,
                   t1::joint_command_t& out);

  int32_t fault_bits() const { return latched_bits_ | warning_bits_; }
  const char* last_fault() const { return last_fault_.data(); }
  const char* last_info() const { return last_info_.data(); }

 private:
  void set_info(const char* text);
  void enter(Mode mode, const StateView& state);
  void autostart_request(const StateView& state);
  void clamp_targets(const StateView& state, const JointArray& kp, const JointArray& kd, JointArray& target);
  int watch_motors(const StateView& state, int32_t* bit, char* why, std::size_t why_size);
  void remember_command(const t1::joint_command_t& out);
  struct StateSource {  // rule R12: the followed stream of one state channel
    const char* channel;
    bool have = false;
    double last_s = 0.0;  // CLOCK_MONOTONIC time of its newest taken frame [s]
  };
  bool accept_state_seq(StateSource& source, SeqTracker& tracker, int64_t seq, double now_s);
  StateSource imu_source_{"T1_IMU"}, joint_source_{"T1_JOINT_STATE"};
  int64_t second_source_frames_ = 0;
  std::array<char, 160> second_source_{};

  // Rules R8, R9, R10: per-motor watch, advanced once per joint state.
  struct MotorWatch {
    int32_t silent_cycles = 0;  // consecutive states without a reply
    bool have_q = false;        // last_q holds a replied encoder value
    float last_q = 0.0f;        // [rad]
    int64_t last_seq = 0;       // joint_seq of that reply
    int32_t frozen_cycles = 0;  // consecutive replies with q bit-identical to the one before, under torque,
                                // away from the stops, while the body moved
    enum Reading : int8_t { kPlausible, kOutside, kJump };
    Reading impossible = kPlausible;  // R10: the latest reply is one no joint can produce
    float impossible_from = 0.0f;     // [rad] the reply before it, and how long before [ms] (for the message)
    float impossible_ms = 0.0f;
  };
  void advance_watch(const StateView& state);
  std::array<MotorWatch, kJoints> watch_{};
  double watched_joint_time_s_ = -1e300;      // the state watch_ has seen last
  float body_rate_radps_ = 0.0f;              // low-passed |IMU angular rate|: R9's evidence that the body turns
  float joint_speed_radps_ = 0.0f;            // low-passed mean |dq| of the motors: R9's evidence that the limbs move
  JointArray cmd_q_{}, cmd_kp_{}, cmd_kd_{};  // the last command sent: what the motors act on now

  SafetyConfig cfg_;
  Mode mode_ = Mode::kPassive;
  bool has_request_ = false;
  Mode requested_ = Mode::kPassive;
  bool entered_policy_ = false;
  bool holding_ = false;
  bool autostart_ = false, operator_hold_ = false;
  int32_t latched_bits_ = 0, warning_bits_ = 0;
  SeqTracker imu_seq_, joint_seq_;
  int64_t prepare_ticks_ = 0, prepare_total_ticks_ = 1;
  JointArray prepare_start_{};
  JointArray last_target_{};  // last commanded q_des [rad]: reference of the rate limit and of "hold"
  bool have_last_target_ = false;
  std::array<char, 160> last_fault_{};
  std::array<char, 160> last_info_{};
};

}  // namespace t1rt
