// Test-side keys: key files (mode 0600) with known keys, and approvals of artifacts, in messages/auth.py's
// formats, so tests can sign as an operator does.
#pragma once
#include <fcntl.h>
#include <gtest/gtest.h>
#include <openssl/sha.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "t1_contract.hpp"
#include "t1rt/command_auth.hpp"

namespace t1rt::testing {

inline std::string test_dir() { return ::testing::TempDir().empty() ? std::string("/tmp/") : ::testing::TempDir(); }
// A file name of this test process's own ("t1rt_<name>_<pid><suffix>"): two test runs at once never share one.
inline std::string own_path(const std::string& name, const std::string& suffix) {
  return test_dir() + "t1rt_" + name + "_" + std::to_string(::getpid()) + suffix;
}

// A key of byte value `fill` for sender `id` (distinct fills: distinct keys).
inline std::pair<int64_t, std::string> test_sender(int64_t id, int fill) {
  char hex[3];
  std::snprintf(hex, sizeof(hex), "%02x", fill & 0xFF);
  std::string key;
  for (std::size_t i = 0; i < kKeyBytes; ++i) key += hex;
  return {id, key};
}

// Writes a key file of these senders with `mode` (0600: accepted) and returns its path.
inline std::string write_key_file(const std::string& name, const std::vector<std::pair<int64_t, std::string>>& senders,
                                  mode_t mode = 0600) {
  const std::string path = own_path(name, ".key");
  ::unlink(path.c_str());
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
  std::string text = "# test key file\n";
  for (const auto& [id, key] : senders) text += std::to_string(id) + " " + key + "\n";
  EXPECT_EQ(::write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  ::fchmod(fd, mode);
  ::close(fd);
  return path;
}

inline std::shared_ptr<const KeyRing> test_ring(const std::string& name,
                                                const std::vector<std::pair<int64_t, std::string>>& senders) {
  std::string error;
  auto ring = KeyRing::load(write_key_file(name, senders), &error);
  EXPECT_TRUE(ring) << error;
  return ring;
}

// Appends sender i's approval of the file at `artifact` to `approvals` (messages/auth.py's approval line).
inline void approve(const KeyRing& ring, std::size_t i, const std::string& approvals, const std::string& artifact) {
  std::ifstream in(artifact, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  uint8_t digest[kSha256Bytes], tag[kTagBytes];
  SHA256(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size(), digest);
  const std::string context = std::string(t1::kApprovalContext) + '\0';
  ASSERT_TRUE(ring.mac(i, context.data(), context.size(), digest, kSha256Bytes, tag));
  auto hex = [](const uint8_t* p, std::size_t n) {
    std::string s;
    char b[3];
    for (std::size_t k = 0; k < n; ++k) s += (std::snprintf(b, sizeof(b), "%02x", p[k]), b);
    return s;
  };
  std::ofstream(approvals, std::ios::app)
      << hex(digest, kSha256Bytes) << " " << ring.sender_id(i) << " " << hex(tag, kTagBytes) << " " << artifact << "\n";
}

}  // namespace t1rt::testing
