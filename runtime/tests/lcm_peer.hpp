// Test-side LCM peer: plays the simulator (publishes T1_IMU / T1_JOINT_STATE / joystick / runtime commands)
// and listens to what the runtime sends, over the real LCM URL ($T1_LCM_URL, inside tools/netns).
#pragma once
#include <lcm/lcm.h>

#include <string>
#include <vector>

#include "t1/controller_status_t.hpp"
#include "t1/imu_t.hpp"
#include "t1/joint_command_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1/joystick_t.hpp"
#include "t1/runtime_cmd_t.hpp"
#include "t1_contract.hpp"
#include "t1rt/transport.hpp"

namespace t1rt::testing {

class LcmPeer {
 public:
  LcmPeer() : lcm_(lcm_create(resolve_lcm_url("").c_str())) {
    if (!lcm_) return;
    lcm_subscribe(lcm_, t1::CH_JOINT_CMD, &LcmPeer::on_cmd, this);
    lcm_subscribe(lcm_, t1::CH_CONTROLLER_STATUS, &LcmPeer::on_status, this);
  }
  ~LcmPeer() { if (lcm_) lcm_destroy(lcm_); }
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
  void command(const std::string& verb, const std::string& arg = "") {
    t1::runtime_cmd_t c{};
    c.verb = verb;
    c.argument = arg;
    publish(t1::CH_RUNTIME_CMD, c);
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
  void drain() { while (lcm_handle_timeout(lcm_, 0) > 0) {} }

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
};

}  // namespace t1rt::testing
