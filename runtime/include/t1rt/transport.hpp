// LCM transport: the subscribed channels are read from a socket of our own on the LCM group
// (messages/cpp/t1_lcm_group.hpp: no receive thread, one wake-up per state message) and decode straight into
// preallocated message slots (the fixed-size state messages decode without heap use); publishing encodes into
// one preallocated buffer and sends it from a socket of our own without waiting (t1_lcm_group.hpp's sender:
// a full send buffer drops the message and counts it in send_dropped(), the loop never blocks on it).
// Heap use that remains, on purpose, off the hot path: runtime_cmd_t carries std::string verb/argument,
// so decoding an operator command allocates (rare, operator-driven, never per tick); verifying a signed
// message allocates inside OpenSSL (command_auth.hpp). runtime_cmd_t and joystick_t are decoded only when
// their tag_size is 0 or 32 (CommandAuth::read_tag_size: their tags decode into reserved capacity) and taken
// only when the CommandAuth and safety rule R11 admit them. imu_t and joint_state_t are read the same way and
// taken only when the robot's verifier (a second CommandAuth with the robot key) takes them, then rules R3 and
// R12 (src/safety_supervisor.cpp); a refused state frame is counted by reason and never reaches the loop.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "t1/imu_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1/joystick_t.hpp"
#include "t1/runtime_cmd_t.hpp"
#include "t1/sim_status_t.hpp"
#include "t1_lcm_group.hpp"
#include "t1rt/command_auth.hpp"
#include "t1rt/safety.hpp"

namespace t1rt {

enum class ClockMode { kRealtime, kLockstep };
const char* clock_name(ClockMode mode);

template <class Message>
struct MessageSlot {
  Message msg{};      // the live message: changes only when a whole datagram decoded and was accepted
  Message scratch{};  // every datagram decodes here first (a truncated one never touches msg)
  bool have = false;
  double stamp_s = 0.0;  // realtime: CLOCK_MONOTONIC receive time; lockstep: msg.utime (sim time) [s]
  int64_t received = 0;
};

// LCM URL: --lcm-url, else $T1_LCM_URL, else t1::kDefaultLcmUrl.
std::string resolve_lcm_url(const std::string& cli_url);

class LcmTransport {
 public:
  static constexpr std::size_t kEncodeBufferBytes = 64 * 1024;
  static constexpr std::size_t kCommandQueue = 8;

  LcmTransport() = default;
  ~LcmTransport();
  LcmTransport(const LcmTransport&) = delete;
  LcmTransport& operator=(const LcmTransport&) = delete;

  // Opens the group's receiving and sending sockets and subscribes; false + *error on failure. subscribe_sim_status: composite
  // mode only (T1_SIM_STATUS is privileged simulator truth; a single policy never listens to it).
  // subscribe_robot_state false: the robot's state comes from another transport (DDS), so T1_IMU and
  // T1_JOINT_STATE on LCM are ignored (one source for the live state, never two).
  // auth: who may command (null: nobody but estop). state_auth: whose state is taken (null: every frame).
  bool open(const std::string& url, ClockMode clock, Supervisor* supervisor, CommandAuth* auth, std::string* error,
            bool subscribe_sim_status = false, bool subscribe_robot_state = true, CommandAuth* state_auth = nullptr);
  // open() without the sockets: the subscriptions, slots and buffers (open() calls it; the fuzz harnesses
  // of runtime/fuzz use it alone and hand datagrams to deliver()).
  void attach(ClockMode clock, Supervisor* supervisor, CommandAuth* auth, bool subscribe_sim_status = false,
              bool subscribe_robot_state = true, CommandAuth* state_auth = nullptr);
  // One parsed datagram (t1::parse_lcm_datagram) to its channel's handler; 1 if subscribed, else 0.
  int deliver(const t1::LcmDatagram& m);
  int handle(int timeout_ms);  // >0 handled datagrams (waiting up to timeout_ms for the first), 0 timeout
  void drain();                // handle everything already queued, without waiting

  template <class Message>
  bool publish(const char* channel, const Message& msg) {
    const int size = msg.getEncodedSize();
    if (size < 0 || static_cast<std::size_t>(size) > buffer_.size()) return false;
    if (msg.encode(buffer_.data(), 0, size) != size) return false;
    return sender_.send(channel, buffer_.data(), static_cast<std::size_t>(size));
  }
  // The live slots as the supervisor and the policy read them at now_s (needs_sim_status: composite or chain mode).
  StateView state_view(double now_s, bool needs_sim_status) const {
    StateView s;
    s.now_s = now_s;
    s.have_imu = imu.have;
    s.imu_time_s = imu.stamp_s;
    s.quat = imu.msg.quat;
    s.gyro = imu.msg.gyro;
    s.have_joint = joint.have;
    s.joint_time_s = joint.stamp_s;
    s.joint_seq = joint.msg.seq;
    s.q = joint.msg.q;
    s.dq = joint.msg.dq;
    s.motor_status = joint.msg.motor_status;
    s.needs_sim_status = needs_sim_status;
    s.have_sim_status = sim_status.have;
    s.sim_status_time_s = sim_status.stamp_s;
    s.waist_height_m = sim_status.msg.waist_height;
    s.trunk_height_m = sim_status.msg.trunk_height;
    return s;
  }
  uint64_t send_dropped() const { return sender_.dropped; }  // messages the kernel could not take at once

  MessageSlot<t1::imu_t> imu;
  MessageSlot<t1::joint_state_t> joint;
  MessageSlot<t1::joystick_t> joystick;
  MessageSlot<t1::sim_status_t> sim_status;  // composite mode only; its strings are reserved in open()
  int64_t sim_status_oversized = 0;          // datagrams > kSimStatusMaxBytes, dropped
  bool new_joint_state = false;              // set by an accepted joint_state_t; the lockstep loop clears it
  std::array<t1::runtime_cmd_t, kCommandQueue> commands;  // verbs other than estop, in arrival order
  std::size_t command_count = 0;
  bool estop_pending = false;    // estop never queues, so a full queue cannot drop it (safety rule R2)
  int64_t commands_dropped = 0;  // non-estop commands that found the queue full
  int64_t decode_errors = 0;     // subscribed datagrams that failed to decode, had trailing bytes or came
                                 // in fragments (a message over 64 kB: none of ours)

 private:
  struct Datagram {
    const uint8_t* data;
    uint32_t size;
  };
  using Handler = void (LcmTransport::*)(const Datagram&);
  struct Subscription {
    const char* channel;
    Handler handler;
  };
  static constexpr std::size_t kMaxSubscriptions = 5;

  void on_imu(const Datagram& d);
  void on_joint(const Datagram& d);
  void on_joystick(const Datagram& d);
  void on_sim_status(const Datagram& d);
  void on_command(const Datagram& d);
  // Whether an imu_t / joint_state_t datagram is the robot's: tag_size readable and 0 or 32, decoded into
  // slot.scratch, verified by state_auth_ (a refusal counted and named); then the caller applies R3/R12.
  template <class Message>
  bool robot_frame(MessageSlot<Message>& slot, CommandAuth::Stream stream, const char* channel, const Datagram& d);
  // Whether a runtime_cmd_t / joystick_t datagram may be decoded: its tag_size 0 or 32, else refused
  // (counted, named) whatever its verb; one that ends before its tag_size is a decode error.
  bool decodable(Supervisor::OperatorInput input, const Datagram& d, const char* what);
  // Whether a decoded runtime_cmd_t / joystick_t is obeyed (CommandAuth, rule R11); a refusal is counted.
  template <class Message>
  bool admitted(Supervisor::OperatorInput input, const char* channel, const Datagram& d, const Message& m,
                const char* what);
  void subscribe(const char* channel, Handler handler);
  int handle_queued();  // datagrams read now on subscribed channels
  double stamp(int64_t utime) const;
  template <class Message>
  bool decode_scratch(MessageSlot<Message>& slot, const Datagram& d);
  template <class Message>
  void commit(MessageSlot<Message>& slot);
  t1::runtime_cmd_t command_scratch_;

  t1::LcmGroupSender sender_;
  int sock_ = -1;  // the group's datagrams
  std::vector<uint8_t> rx_;
  std::array<Subscription, kMaxSubscriptions> subscriptions_{};
  std::size_t subscription_count_ = 0;
  ClockMode clock_ = ClockMode::kRealtime;
  Supervisor* supervisor_ = nullptr;
  CommandAuth* auth_ = nullptr;
  CommandAuth* state_auth_ = nullptr;
  std::vector<uint8_t> buffer_;
};

}  // namespace t1rt
