// The simulator's LCM robot link (sim_hil/lcm_bridge.py's engine): publishes T1_IMU and T1_JOINT_STATE,
// receives T1_JOINT_CMD, and turns a valid command into the 23 CAN command frames at once. An unusable
// command (undecodable, non-finite, gains outside the frame's range) is counted and dropped with a reason.
// Commands are read from a socket of the link's own on the LCM group (messages/cpp/t1_lcm_group.hpp), not
// through an LCM subscription, which would wake a receive thread for every datagram, the sim's own included;
// states go out from one preallocated buffer through that header's sender, which never waits or allocates.
// With a robot key (set_robot_key) every imu_t / joint_state_t is signed as messages/auth.py says: sender_id,
// timestamp_us (the wall clock, strictly increasing per channel), tag = HMAC-SHA256 through OpenSSL.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "t1_firmware.h"
#include "t1_lcm_group.hpp"

struct evp_mac_ctx_st;

namespace t1sim {

struct StateReading {  // what one state message pair carries (joint order, SI units)
  int64_t utime_us, seq;
  const double *quat, *gyro, *accel;  // 4, 3, 3
  const double *q, *dq, *tau;         // NUM_MOTORS each
  const int32_t* status;
};

class RobotLink {
 public:
  explicit RobotLink(const std::string& url);
  ~RobotLink();
  RobotLink(const RobotLink&) = delete;
  RobotLink& operator=(const RobotLink&) = delete;
  bool good() const { return sender_.good() && sock_ >= 0; }

  void publish_state(const StateReading& s);
  // Signs the state from now on as sender_id with this key (32 bytes); false when OpenSSL cannot key it.
  bool set_robot_key(int64_t sender_id, const uint8_t* key, std::size_t size);
  // 0 sent, -1 not (LCM's convention): the Python side's status and fault messages
  int publish(const std::string& channel, const void* data, int size) {
    return size >= 0 && sender_.send(channel.c_str(), data, static_cast<std::size_t>(size)) ? 0 : -1;
  }
  uint64_t send_dropped() const { return sender_.dropped; }
  // Handle what is queued, then wait up to timeout_s [s] (to the microsecond) for more.
  void poll(double timeout_s);
  // Lockstep: handle commands until the one answering state_seq arrived (true) or timeout_s passed.
  bool wait_for_answer(int64_t state_seq, double timeout_s);

  bool has_latest() const { return !latest_payload_.empty(); }
  int64_t latest_state_seq() const { return latest_state_seq_; }
  const std::vector<uint8_t>& latest_payload() const { return latest_payload_; }
  // The newest valid command's frames, once: a command goes on the bus once, as on the robot.
  bool take_frames(uint8_t* out);

  uint64_t received = 0, dropped = 0;
  std::string last_drop_reason;

 private:
  template <class Message>
  void send(const char* channel, Message& msg, int stream);  // encoded into tx_ (signed with a robot key),
                                                             // then sent (or counted dropped)
  void on_command(const uint8_t* payload, size_t size);
  int handle_queued();  // commands read from the socket now; returns how many datagrams were read
  void drop(const std::string& reason);

  t1::LcmGroupSender sender_;
  std::vector<uint8_t> tx_;  // one encoded state message
  int sock_ = -1;
  std::vector<uint8_t> rx_;  // one datagram
  std::vector<uint8_t> latest_payload_;
  int64_t latest_state_seq_ = -1;
  uint8_t frames_[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES] = {};
  bool fresh_ = false;
  int reported_ = 0;
  evp_mac_ctx_st* mac_ = nullptr;  // keyed HMAC-SHA256 context of the robot key (null: unsigned state)
  int64_t sender_id_ = 0;
  std::array<int64_t, 2> last_us_{};  // the last timestamp per state channel (imu, joint)
};

}  // namespace t1sim
