// The robot-facing transport over Cyclone DDS, in the Booster T1's own low-level topics
// (messages/contract.json "dds"; types generated from messages/dds/booster_low.idl):
//   rt/low_state (LowState_: IMU rpy/gyro/acc + serial motor states) in,
//   rt/joint_ctrl (LowCmd_: SERIAL, 23 MotorCmd_) out.
// A RobotLink (robot_link.hpp): it fills the same live slots (imu_t, joint_state_t) the LCM link fills, so
// the observation, supervisor and policy code do not know which link feeds them. Operator channels (joystick,
// runtime_cmd) and telemetry (status, obs, action) stay on LCM.
//
// Safety rule R3 on this transport: a sample is checked whole before it may replace the live state (23
// serial motors, every number finite); a rejected sample is counted and the state is left unchanged.
// LowState_ carries no sequence number: the runtime numbers accepted samples in arrival order and adds
// the samples DDS reports lost (SAMPLE_LOST status), so the supervisor sees a loss as a sequence gap.
//
// One writer (safety rule R12 on DDS): the runtime follows the rt/low_state writer of its first valid sample
// (the sample info's publication handle; its GUID named in the status). A sample of another writer is
// refused, counted and named with that writer's GUID while the followed one is alive (a sample of it taken
// less than SafetyConfig::restart_quiet_s ago); after that silence the new writer is followed (the robot's
// own stack restarted).
#pragma once
#include <dds/dds.h>

#include <array>
#include <cstdint>
#include <string>

#include "booster_low.h"
#include "t1/imu_t.hpp"
#include "t1/joint_command_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1rt/constants.hpp"
#include "t1rt/robot_link.hpp"
#include "t1rt/transport.hpp"

namespace t1rt {

using DdsLowState = booster_interface_msg_dds__LowState_;
using DdsLowCmd = booster_interface_msg_dds__LowCmd_;
using DdsMotorCmd = booster_interface_msg_dds__MotorCmd_;

// Why a LowState_ sample is unusable, or nullptr when it is usable.
const char* check_low_state(const DdsLowState& sample);
// A usable sample into the project's state messages (seq and utime are the caller's): quaternion from rpy
// (quat_from_rpy, policy.hpp), q / dq / tau_est from the serial motor states. motor_status: the robot
// reports no firmware bits in LowState_, only T1_STATUS_NO_REPLY where MotorState_.lost differs from
// prev_lost[i], the previous accepted sample's (nullptr: first sample); mode and temperature are not read
// (messages/dds/booster_low.idl says why).
void low_state_to_messages(const DdsLowState& sample, t1::imu_t* imu, t1::joint_state_t* joint,
                           const uint32_t* prev_lost = nullptr);
// The supervisor's command as a LowCmd_ (SERIAL, the CUSTOM-mode mode/weight of the contract) into
// motors[kJoints]; out->motor_cmd must point at motors.
void joint_command_to_low_cmd(const t1::joint_command_t& cmd, DdsLowCmd* out, DdsMotorCmd* motors);

class DdsTransport final : public RobotLink {
 public:
  static constexpr int kTakeBatch = 8;  // samples taken per dds_take call

  DdsTransport() = default;
  ~DdsTransport();
  DdsTransport(const DdsTransport&) = delete;
  DdsTransport& operator=(const DdsTransport&) = delete;

  // Creates the participant, the two topics, the state reader and the command writer; the accepted state
  // lands in imu / joint (seq checked by the supervisor), and *new_state is set for each accepted sample.
  bool open(int domain_id, ClockMode clock, Supervisor* supervisor, MessageSlot<t1::imu_t>* imu,
            MessageSlot<t1::joint_state_t>* joint, bool* new_state, std::string* error,
            double restart_quiet_s = SafetyConfig{}.restart_quiet_s);
  // open() without DDS: where accepted samples go (open() calls it; runtime/fuzz uses it with accept() alone).
  void attach(ClockMode clock, Supervisor* supervisor, MessageSlot<t1::imu_t>* imu,
              MessageSlot<t1::joint_state_t>* joint, bool* new_state);
  // One deserialised rt/low_state sample of the followed writer: checked (R3), numbered, into the slots.
  void accept(const DdsLowState& sample);
  int wait(int timeout_ms) override;  // waits for a state sample, takes what is queued; >0 took one, 0 timeout
  void drain() override;              // takes everything queued, without waiting
  bool publish(const t1::joint_command_t& cmd) override;
  int64_t rejected_samples() const override { return rejected; }
  const char* last_rejection() const override { return rejected ? last_reject.data() : ""; }
  int64_t second_writer_samples() const override { return other_writer_samples; }
  const char* second_writer() const override { return other_writer.data(); }

  int64_t rejected = 0;                  // samples refused by check_low_state (state unchanged)
  int64_t lost = 0;                      // samples DDS reports lost before they reached the reader
  std::array<char, 160> last_reject{};   // why the newest rejected sample was refused
  int64_t other_writer_samples = 0;      // samples of a writer other than the followed one, refused
  int64_t writer_changes = 0;            // followed writers replaced after the old one fell silent
  std::array<char, 48> followed{};       // the followed writer's GUID (hex), "" before the first sample
  std::array<char, 160> other_writer{};  // the newest refused writer, named with its GUID ("" until one)

 private:
  int take();
  // Whether a sample of `writer` is the followed writer's (adopting a first one, or a new one after the
  // followed one's silence); a refused one is counted and named.
  bool from_followed_writer(dds_instance_handle_t writer, double now_s);
  void format_guid(dds_instance_handle_t writer, std::array<char, 48>* out) const;

  dds_entity_t participant_ = 0, state_reader_ = 0, cmd_writer_ = 0, waitset_ = 0;
  ClockMode clock_ = ClockMode::kRealtime;
  Supervisor* supervisor_ = nullptr;
  MessageSlot<t1::imu_t>* imu_ = nullptr;
  MessageSlot<t1::joint_state_t>* joint_ = nullptr;
  bool* new_state_ = nullptr;
  int64_t accepted_ = 0;  // arrival-order number of the next accepted sample
  double restart_quiet_s_ = 0.0;
  dds_instance_handle_t writer_ = 0, named_other_ = 0;  // the followed writer, the last one named refused
  double writer_last_s_ = 0.0;                          // CLOCK_MONOTONIC time of its newest sample [s]
  std::array<uint32_t, kJoints> lost_seen_{};           // MotorState_.lost of the last accepted sample
  std::array<DdsMotorCmd, kJoints> motors_{};
  DdsLowCmd low_cmd_{};
};

}  // namespace t1rt
