// Test-side LCM peer: plays the simulator (publishes T1_IMU / T1_JOINT_STATE / joystick / runtime commands)
// and listens to what the runtime sends, over the real LCM URL ($T1_LCM_URL, inside tools/netns).
#pragma once
#include <lcm/lcm.h>

#include <algorithm>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include "t1/controller_status_t.hpp"
#include "t1/imu_t.hpp"
#include "t1/joint_command_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1/joystick_t.hpp"
#include "t1/runtime_cmd_t.hpp"
#include "t1_contract.hpp"
#include "t1rt/command_auth.hpp"
#include "t1rt/transport.hpp"

namespace t1rt::testing {

class LcmPeer {
 public:
  LcmPeer() : lcm_(lcm_create(resolve_lcm_url("").c_str())) {
    if (!lcm_) return;
    lcm_subscribe(lcm_, t1::CH_JOINT_CMD, &LcmPeer::on_cmd, this);
    lcm_subscribe(lcm_, t1::CH_CONTROLLER_STATUS, &LcmPeer::on_status, this);
  }
  ~LcmPeer() {
    if (lcm_) lcm_destroy(lcm_);
  }
  bool ok() const { return lcm_ != nullptr; }

  template <class M>
  void publish(const char* channel, const M& m) {
    std::vector<uint8_t> buf(m.getEncodedSize());
    m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm_publish(lcm_, channel, buf.data(), static_cast<unsigned>(buf.size()));
  }
  void publish_raw(const char* channel, const uint8_t* data, std::size_t size) {
    lcm_publish(lcm_, channel, data, static_cast<unsigned>(size));
  }
  // From here on, command() and publish_signed() sign as sender i of ring (messages/auth.py).
  void sign_with(std::shared_ptr<const KeyRing> ring, std::size_t i = 0) {
    ring_ = std::move(ring);
    sender_ = i;
  }
  // A runtime_cmd_t or joystick_t with this peer's sender id, a fresh timestamp and its tag.
  template <class M>
  void publish_signed(const char* channel, M m) {
    publish_signed_by(*ring_, sender_, channel, std::move(m));
  }
  // The same signed by sender i of another ring (the robot key: imu_t, joint_state_t).
  template <class M>
  void publish_signed_by(const KeyRing& ring, std::size_t i, const char* channel, M m) {
    m.sender_id = ring.sender_id(i);
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    last_us_ = std::max(last_us_ + 1, static_cast<int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000);
    m.timestamp_us = last_us_;
    const std::vector<uint8_t> buf = ring.encode_signed(i, channel, m);
    lcm_publish(lcm_, channel, buf.data(), static_cast<unsigned>(buf.size()));
  }
  void command(const std::string& verb, const std::string& arg = "") {
    t1::runtime_cmd_t c{};
    c.verb = verb;
    c.argument = arg;
    if (ring_) publish_signed(t1::CH_RUNTIME_CMD, c);
    else publish(t1::CH_RUNTIME_CMD, c);
  }
  // Waits for the joint command answering state `seq`; false on timeout.
  bool wait_command(int64_t seq, int timeout_ms = 500) {
    for (int waited = 0; waited < timeout_ms; waited += 10) {
      while (lcm_handle_timeout(lcm_, 10) > 0)
        if (have_cmd && last_cmd.state_seq == seq) return true;
      if (have_cmd && last_cmd.state_seq == seq) return true;
    }
    return false;
  }
  void drain() {
    while (lcm_handle_timeout(lcm_, 0) > 0) {
    }
  }

  t1::joint_command_t last_cmd{};
  bool have_cmd = false;
  t1::controller_status_t last_status{};
  int statuses = 0;

 private:
  static void on_cmd(const lcm_recv_buf_t* rb, const char*, void* p) {
    auto* self = static_cast<LcmPeer*>(p);
    if (self->last_cmd.decode(rb->data, 0, rb->data_size) >= 0) self->have_cmd = true;
  }
  static void on_status(const lcm_recv_buf_t* rb, const char*, void* p) {
    auto* self = static_cast<LcmPeer*>(p);
    if (self->last_status.decode(rb->data, 0, rb->data_size) >= 0) ++self->statuses;
  }
  lcm_t* lcm_;
  std::shared_ptr<const KeyRing> ring_;
  std::size_t sender_ = 0;
  int64_t last_us_ = 0;  // timestamps strictly increase on both channels
};

}  // namespace t1rt::testing
