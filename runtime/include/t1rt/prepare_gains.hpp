// PD gains of the PREPARE mode: the real T1's stand-up ("prepare") gains, as booster_gym's deploy sends
// them before it switches to CUSTOM and the policy's gains (../shared/booster_dds.md "Modes and the deploy
// sequence"). Defined once in messages/contract.json (supervisor.prepare.gains, joint order = the contract's),
// which training's PREPARE model reads too. Why not the policy's gains: with them a static hold of the default
// pose tips this model over after ~1.3 s (ankle kp 50 cannot hold the trunk's sway), with these (ankle kp 450)
// it stands: a standing robot must stay up while the operator prepares it, before any policy runs.
#pragma once
#include "t1_contract.hpp"
#include "t1rt/artifact.hpp"

namespace t1rt {

inline constexpr JointArray kPrepareKp = t1::kPrepareKpNmPerRad;   // [N·m/rad]
inline constexpr JointArray kPrepareKd = t1::kPrepareKdNmsPerRad;  // [N·m·s/rad]

}  // namespace t1rt
