// Chain mode: the keyframe getup as it ships (policies/getup_keyframe/, common/keyframe_chain.py), three members
// switched and latched by the rules of common/events.keyframe_stage: roll until the robot lies face down and
// still, rise until the kneel hand-over (§4.8's gate or the kneel band, named by the chain's manifest), stand
// until the Trunk is down; a rise that tipped the robot onto its back or side goes back to the roll.
//
// The Trunk's height is a PRIVILEGED simulator signal (T1_SIM_STATUS, sim_status_t.trunk_height), as the
// composite's waist height: chain mode is for evaluation in the simulator, and the runtime says so. The rest
// (the Trunk's up and forward axes, its angular speed) comes from the IMU.
#pragma once
#include <array>
#include <cstdint>
#include <string>

#include "t1_contract.hpp"

namespace t1rt {

inline constexpr const char* kChainManifest = "chain.json";
inline constexpr const char* kChainFormat = "t1-keyframe-chain/1";

enum class ChainStage : int8_t { kStart = -1, kRoll = 0, kRise = 1, kStand = 2 };
inline constexpr std::size_t kChainStages = 3;
const char* stage_name(ChainStage stage);

// A chain folder's manifest: its members' files (roll, rise, stand) and the rise → stand hand-over.
struct ChainFile {
  std::array<std::string, kChainStages> members;    // paths, in ChainStage order
  std::string handover;                             // "kneel_gate" | "kneel_band"
  float handover_up_error = t1::kKneelGateUpError;  // its upright bound ‖u − e_z‖ (the contract's)
};

bool is_chain_folder(const std::string& path);  // a folder holding chain.json
// Throws ArtifactError (field "chain.json" or "chain.json: stages.X") naming what is missing or malformed.
ChainFile read_chain_file(const std::string& folder);

struct TrunkReadings {
  float height_m = 0.0f;         // the Trunk origin's height above the floor [m] (sim status)
  float up_z = 1.0f;             // world z of the Trunk's z axis
  float forward_z = 0.0f;        // world z of the Trunk's x axis
  float ang_speed_rad_s = 0.0f;  // |gyro| [rad/s]
};
// From the IMU's orientation (w x y z) and gyro [rad/s], and the sim's Trunk height [m].
TrunkReadings trunk_readings(const float quat_wxyz[4], const float gyro[3], float trunk_height_m);

// The stage that acts this policy tick, from the one that acted the last (kStart at the first tick of POLICY:
// the Trunk's height picks it). The same rules as common/events.keyframe_stage.
ChainStage next_stage(ChainStage stage, const TrunkReadings& r, float handover_up_error);

}  // namespace t1rt
