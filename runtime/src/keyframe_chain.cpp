#include "t1rt/keyframe_chain.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "t1rt/artifact.hpp"

namespace t1rt {

namespace fs = std::filesystem;

const char* stage_name(ChainStage stage) {
  switch (stage) {
    case ChainStage::kRoll:
      return "roll";
    case ChainStage::kRise:
      return "rise";
    case ChainStage::kStand:
      return "stand";
    default:
      return "start";
  }
}

bool is_chain_folder(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec) && fs::is_regular_file(fs::path(path) / kChainManifest, ec);
}

ChainFile read_chain_file(const std::string& folder) {
  const fs::path manifest = fs::path(folder) / kChainManifest;
  std::ifstream in(manifest);
  if (!in) throw ArtifactError(kChainManifest, folder + ": not a keyframe chain (no readable chain.json)");
  const nlohmann::json data = nlohmann::json::parse(in, nullptr, false);
  if (data.is_discarded() || !data.is_object())
    throw ArtifactError(kChainManifest, manifest.string() + ": not a JSON object");
  if (data.value("format", std::string()) != kChainFormat)
    throw ArtifactError(kChainManifest, manifest.string() + ": format must be \"" + kChainFormat + "\"");
  const auto stages = data.find("stages");
  if (stages == data.end() || !stages->is_object() || stages->size() != kChainStages)
    throw ArtifactError(kChainManifest, manifest.string() + ": stages must name exactly roll, rise, stand");
  ChainFile chain;
  for (std::size_t i = 0; i < kChainStages; ++i) {
    const char* name = stage_name(static_cast<ChainStage>(i));
    const std::string field = std::string(kChainManifest) + ": stages." + name;
    const auto it = stages->find(name);
    if (it == stages->end() || !it->is_string()) throw ArtifactError(field, "missing, or not a file name");
    const std::string file = it->get<std::string>();
    if (file.empty() || fs::path(file).filename().string() != file)
      throw ArtifactError(field, "'" + file + "' must be a file name in the chain's folder");
    const fs::path path = fs::path(folder) / file;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) throw ArtifactError(field, path.string() + " does not exist");
    chain.members[i] = path.string();
  }
  chain.handover = data.value("handover", std::string());
  if (chain.handover == "kneel_gate") chain.handover_up_error = t1::kKneelGateUpError;
  else if (chain.handover == "kneel_band") chain.handover_up_error = t1::kKneelBandUpError;
  else
    throw ArtifactError(std::string(kChainManifest) + ": handover",
                        "must be kneel_gate or kneel_band, got '" + chain.handover + "'");
  return chain;
}

TrunkReadings trunk_readings(const float q[4], const float gyro[3], float trunk_height_m) {
  const float w = q[0], x = q[1], y = q[2], z = q[3];
  const float norm2 = w * w + x * x + y * y + z * z;
  TrunkReadings r;
  r.height_m = trunk_height_m;
  r.up_z = 1.0f - 2.0f * (x * x + y * y) / norm2;
  r.forward_z = 2.0f * (x * z - w * y) / norm2;
  r.ang_speed_rad_s = std::sqrt(gyro[0] * gyro[0] + gyro[1] * gyro[1] + gyro[2] * gyro[2]);
  return r;
}

namespace {
bool lying(const TrunkReadings& r) { return r.height_m < t1::kFallenTrunkHeightM; }
bool still(const TrunkReadings& r) { return r.ang_speed_rad_s < t1::kRolledMaxAngSpeedRadS; }
// §4.8's gate with the hand-over's upright bound: H − min(h, H) < tol and ‖u − e_z‖ = √(2 − 2·u_z) < bound.
bool at_kneel(const TrunkReadings& r, float up_error_max) {
  const float h = t1::kKneelGateHeightM;
  return h - std::min(r.height_m, h) < t1::kKneelGateHeightTolM &&
         std::sqrt(std::max(2.0f - 2.0f * r.up_z, 0.0f)) < up_error_max;
}
}  // namespace

ChainStage next_stage(ChainStage stage, const TrunkReadings& r, float handover_up_error) {
  if (stage == ChainStage::kStart)
    stage = lying(r)                                    ? ChainStage::kRoll
            : r.height_m < t1::kStandingTrunkThresholdM ? ChainStage::kRise
                                                        : ChainStage::kStand;
  switch (stage) {
    case ChainStage::kRoll:
      return lying(r) && still(r) && r.forward_z < -t1::kRolledForwardZ ? ChainStage::kRise : ChainStage::kRoll;
    case ChainStage::kRise:
      if (at_kneel(r, handover_up_error)) return ChainStage::kStand;
      // lying still on the back or side (not face down): the roll turns it over again
      return lying(r) && still(r) && r.forward_z > -t1::kLyingFacingZ ? ChainStage::kRoll : ChainStage::kRise;
    default:
      return lying(r) ? ChainStage::kRoll : ChainStage::kStand;
  }
}

}  // namespace t1rt
