// Fixed numbers of the runtime: loop rate, decimation, message sizes. The loop and policy rates are the
// contract's (messages/contract.json through the generated t1_contract.hpp); tunable safety numbers live in
// SafetyConfig (safety.hpp); the robot's joint table lives in firmware_like (t1_motor_protocol.h).
#pragma once
#include <cstddef>
#include <cstdint>

#include "t1_contract.hpp"

namespace t1rt {

inline constexpr std::size_t kJoints = 23;            // = t1::kNumJoints = T1_NUM_MOTORS (checked statically)
inline constexpr double kLoopDtS = t1::kLoopPeriodS;  // control loop period [s]
inline constexpr int64_t kLoopPeriodNs = static_cast<int64_t>(t1::kLoopPeriodS * 1e9 + 0.5);  // same, [ns]
inline constexpr int kPolicyDecimation = t1::kPolicyDecimation;  // the policy runs every kPolicyDecimation-th tick
inline constexpr double kControlDtToleranceS = 1e-9;  // artifact control_dt must match the policy period within this
inline constexpr int kStatusEveryTicks = 50;          // T1_CONTROLLER_STATUS at 10 Hz
inline constexpr std::size_t kTimingWindow = 1024;    // samples in the p99 window (about 2 s at 500 Hz)
inline constexpr int kSchemaVersion = 1;              // policies/ARTIFACT.md schema handled here
// Documented maxima of artifact manifest numbers (policies/ARTIFACT.md "Limits"); beyond them a value is a
// unit error or a typo, not a policy. Sign and joint-range rules are in the loader.
inline constexpr double kMaxActionScaleRad = 2.0;    // target = default + scale * action [rad per unit]: the
                                                     // getup experts need 2 (kneel knee 1.5 rad from home)
inline constexpr double kMaxGaitFrequencyHz = 5.0;   // a walking gait clock; the T1 steps at about 1.5 Hz
inline constexpr double kMaxCommandMagnitude = 5.0;  // |command_ranges| [m/s or rad/s]: far above the T1's speeds

}  // namespace t1rt
