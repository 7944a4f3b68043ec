// libFuzzer harness: a policy artifact file (safetensors: u64 header length, JSON header with the manifest
// in __metadata__, tensor bytes), read as --policy and a hot reload read it.
// Path: parse_artifact (what load_artifact and PolicyStore::load_path run on the file's bytes: header,
// manifest fields, tensor entries, content hash) -> for an accepted artifact, the PolicyEngine the runtime
// builds from it and one policy step. Every refusal must be an ArtifactError (the runtime's one-line refusal).
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace t1rt;
  const std::string file(reinterpret_cast<const char*>(data), size);
  PolicyArtifact artifact;
  try {
    artifact = parse_artifact("fuzz.safetensors", file);
  } catch (const ArtifactError&) {
    return 0;  // the refusal t1-runtime prints and exits 3 on
  }
  PolicyEngine engine(std::move(artifact));
  engine.reset();
  const float quat[4] = {1, 0, 0, 0}, gyro[3] = {0, 0, 0}, command[3] = {0.5f, 0, 0};
  const auto& pose = engine.artifact().default_pose;
  const float dq[kJoints] = {};
  engine.step(quat, gyro, command, pose.data(), dq);
  return 0;
}
