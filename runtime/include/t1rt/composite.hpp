// Composite mode: a stitched pair of policies switched by waist height, as the seed's teacher and
// baseline do (getup expert while the Waist body is below 0.5 m, else the upright/joystick policy).
//
// The waist height is a PRIVILEGED simulator signal (T1_SIM_STATUS, sim_status_t.waist_height): a real
// T1 cannot measure it. The runtime subscribes to T1_SIM_STATUS only in this mode, and says so in its
// status (policy_name "composite[...]", info "composite: waist from T1_SIM_STATUS ...") and live line.
// A stale sim status is treated like stale state (Supervisor: > hold age holds the last target, > fault
// age latches FAULT), so the sim must publish it every tick: `python -m sim_hil --status-rate 500`.
#pragma once
#include "t1_contract.hpp"
#include "t1rt/artifact.hpp"

namespace t1rt {

// The switch height is the contract's (messages/contract.json waist_switch_height_m).
inline constexpr float kGetupSwitchWaistHeightM = t1::kWaistSwitchHeightM;
inline constexpr std::size_t kSimStatusMaxBytes = 4096;  // larger sim_status_t datagrams are dropped
                                                         // (their strings would outgrow the reserve)

enum class CompositeMember : int8_t { kGetup = 0, kUpright = 1 };
const char* member_name(CompositeMember member);

// The teacher's rule, with no hysteresis (the teacher has none): getup strictly below the switch height.
inline CompositeMember select_member(float waist_height_m) {
  return waist_height_m < kGetupSwitchWaistHeightM ? CompositeMember::kGetup : CompositeMember::kUpright;
}

// Both artifacts are already validated one by one (load_artifact). A pair must also share ONE gain set
// (the student cannot switch gains, so the baseline may not either) and the control period. Throws
// ArtifactError naming the field and the first differing joint.
void check_composite_pair(const PolicyArtifact& getup, const PolicyArtifact& upright);

}  // namespace t1rt
