// The robot link's one choice between LCM and DDS (robot_link.hpp); nothing else in the runtime makes it.
#include "t1rt/robot_link.hpp"

#include "t1_contract.hpp"
#include "t1rt/dds_transport.hpp"

namespace t1rt {

const char* robot_link_description(RobotLinkKind kind) {
  return kind == RobotLinkKind::kDds ? "DDS (rt/low_state -> rt/joint_ctrl)" : "LCM";
}

bool LcmRobotLink::publish(const t1::joint_command_t& cmd) { return lcm_->publish(t1::CH_JOINT_CMD, cmd); }

std::unique_ptr<RobotLink> open_robot_link(RobotLinkKind kind, int dds_domain_id, ClockMode clock,
                                           Supervisor* supervisor, LcmTransport* lcm, std::string* error,
                                           double restart_quiet_s) {
  if (kind == RobotLinkKind::kLcm) return std::make_unique<LcmRobotLink>(lcm);
  auto dds = std::make_unique<DdsTransport>();
  if (!dds->open(dds_domain_id, clock, supervisor, &lcm->imu, &lcm->joint, &lcm->new_joint_state, error,
                 restart_quiet_s))
    return nullptr;
  return dds;
}

}  // namespace t1rt
