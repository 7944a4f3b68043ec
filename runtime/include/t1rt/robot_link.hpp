// The link to the robot: the robot's state in, joint commands out. Two links implement it:
//   LCM: T1_IMU / T1_JOINT_STATE in, T1_JOINT_CMD out, on the LCM transport the operator's channels use;
//   DDS: the Booster T1's own rt/low_state in, rt/joint_ctrl out (dds_transport.hpp).
// Both fill the same live state slots (LcmTransport::imu / joint, transport.hpp), so the controller, the
// observation and the supervisor never ask which link runs. Operator channels and telemetry stay on LCM.
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "t1/joint_command_t.hpp"
#include "t1rt/safety.hpp"
#include "t1rt/transport.hpp"

namespace t1rt {

enum class RobotLinkKind { kLcm, kDds };
const char* robot_link_description(RobotLinkKind kind);
// Whether the robot's state arrives on the LCM transport (T1_IMU / T1_JOINT_STATE subscribed there).
inline bool state_on_lcm(RobotLinkKind kind) { return kind == RobotLinkKind::kLcm; }

class RobotLink {
 public:
  virtual ~RobotLink() = default;
  // Waits up to timeout_ms for the robot's state; >0 handled some, 0 timeout, <0 error.
  virtual int wait(int timeout_ms) = 0;
  virtual void drain() = 0;  // takes what the robot sent already, without waiting
  virtual bool publish(const t1::joint_command_t& cmd) = 0;
  // State samples the link itself refused whole (state unchanged), and why the newest was ("" if none).
  virtual int64_t rejected_samples() const { return 0; }
  virtual const char* last_rejection() const { return ""; }
  // Samples of a second state writer the link itself refused (rule R12 at the link), and that writer named.
  virtual int64_t second_writer_samples() const { return 0; }
  virtual const char* second_writer() const { return ""; }
};

// The LCM link: the robot's frames arrive on the LCM transport's socket (taken there through the robot's
// verifier and rules R3 / R12), its commands leave on T1_JOINT_CMD.
class LcmRobotLink final : public RobotLink {
 public:
  explicit LcmRobotLink(LcmTransport* lcm) : lcm_(lcm) {}
  int wait(int timeout_ms) override { return lcm_->handle(timeout_ms); }
  void drain() override {}  // the LCM transport's own drain, once per tick, takes the robot's frames too
  bool publish(const t1::joint_command_t& cmd) override;

 private:
  LcmTransport* lcm_;
};

// The link of `kind` over the opened LCM transport `lcm` (whose slots it fills); null + *error on failure.
std::unique_ptr<RobotLink> open_robot_link(RobotLinkKind kind, int dds_domain_id, ClockMode clock,
                                           Supervisor* supervisor, LcmTransport* lcm, std::string* error,
                                           double restart_quiet_s = SafetyConfig{}.restart_quiet_s);

}  // namespace t1rt
