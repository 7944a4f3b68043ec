// PD gains of the PREPARE mode: the real T1's stand-up ("prepare") gains, as booster_gym's deploy sends
// them before it switches to CUSTOM and the policy's gains (../shared/booster_dds.md "Modes and the deploy
// sequence"; values: BG deploy/configs/T1.yaml `prepare`, ../shared/t1_facts.md §2c, joint order = the
// contract's). Why not the policy's gains: with them a static hold of the default pose tips this model over
// after ~1.3 s (ankle kp 50 cannot hold the trunk's sway), with these (ankle kp 450) it stands: a
// standing robot must stay up while the operator prepares it, before any policy runs.
#pragma once
#include "t1rt/artifact.hpp"

namespace t1rt {

//                                       head      left arm (sh. pitch, sh. roll, elbow pitch, elbow yaw)
inline constexpr JointArray kPrepareKp{5.0f, 5.0f, 40.0f, 50.0f, 20.0f, 10.0f,
                                       40.0f, 50.0f, 20.0f, 10.0f,             // right arm
                                       100.0f,                                 // waist
                                       350.0f, 350.0f, 180.0f, 350.0f, 450.0f, 450.0f,   // left leg [N·m/rad]
                                       350.0f, 350.0f, 180.0f, 350.0f, 450.0f, 450.0f};  // right leg
inline constexpr JointArray kPrepareKd{0.1f, 0.1f, 0.5f, 1.5f, 0.2f, 0.2f,
                                       0.5f, 1.5f, 0.2f, 0.2f,
                                       5.0f,
                                       7.5f, 7.5f, 3.0f, 5.5f, 0.5f, 0.5f,               // [N·m·s/rad]
                                       7.5f, 7.5f, 3.0f, 5.5f, 0.5f, 0.5f};

}  // namespace t1rt
