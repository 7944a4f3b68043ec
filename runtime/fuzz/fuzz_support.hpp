// Shared by the runtime's libFuzzer harnesses: a key ring of one sender with a fresh random key (written to a
// 0600 temp file, as KeyRing::load requires), a small valid policy, and the loop's use of an accepted state
// (Supervisor phase 1 + 2 and one policy step), so a harness reaches what the loop would see.
#pragma once
#include <gtest/gtest.h>  // test_artifact.hpp's temp_path names ::testing::TempDir (never called here)
#include <openssl/rand.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "../tests/test_artifact.hpp"
#include "t1/joint_command_t.hpp"
#include "t1rt/command_auth.hpp"
#include "t1rt/policy.hpp"
#include "t1rt/safety.hpp"

namespace t1rt::fuzz {

inline constexpr int64_t kSenderId = 7;  // the one sender of the harness's key ring

// Loaded once per process; the key never leaves this process (the temp file is removed at once).
inline std::shared_ptr<const KeyRing> key_ring() {
  static std::shared_ptr<const KeyRing> ring = [] {
    uint8_t key[kKeyBytes];
    if (RAND_bytes(key, sizeof(key)) != 1) std::abort();
    char path[] = "/tmp/t1_fuzz_keyXXXXXX";  // mkstemp: mode 0600
    const int fd = mkstemp(path);
    if (fd < 0) std::abort();
    std::string line = std::to_string(kSenderId) + " ";
    for (uint8_t b : key) {
      char hex[3];
      std::snprintf(hex, sizeof(hex), "%02x", b);
      line += hex;
    }
    line += "\n";
    if (write(fd, line.data(), line.size()) != static_cast<ssize_t>(line.size())) std::abort();
    close(fd);
    std::string error;
    auto loaded = KeyRing::load(path, &error);
    unlink(path);
    if (!loaded) {
      std::fprintf(stderr, "fuzz: key ring: %s\n", error.c_str());
      std::abort();
    }
    return loaded;
  }();
  return ring;
}

// A small valid policy (hidden 8, 8): the artifact the supervisor and the policy step run with.
inline const PolicyArtifact& small_artifact() {
  static const PolicyArtifact a = parse_artifact("fuzz_policy", testing::serialise(testing::make_spec({8, 8})));
  return a;
}

// What one loop tick does with the live state: supervisor phase 1, the policy on it, phase 2.
inline void loop_tick(Supervisor& supervisor, PolicyEngine& engine, const StateView& state, const float* command) {
  const PolicyArtifact& a = engine.artifact();
  if (supervisor.begin_tick(state, a) && state.have_imu && state.have_joint)
    engine.step(state.quat, state.gyro, command, state.q, state.dq);
  t1::joint_command_t out{};
  supervisor.finish_tick(state, a, engine.q_target(), out);
}

}  // namespace t1rt::fuzz
