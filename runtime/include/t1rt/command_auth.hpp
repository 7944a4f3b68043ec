// Who may command the runtime, and whose state it takes: the runtime's side of messages/auth.py (the protocol's one definition, held to
// this code by tests/golden/command_auth.json). runtime_cmd_t and joystick_t carry sender_id, timestamp_us and,
// last, tag_size (0: unsigned, kTagBytes: signed) and tag = HMAC-SHA256(key, channel + NUL + the payload before
// tag_size); an artifact approval is
// HMAC-SHA256(key, t1::kApprovalContext + NUL + the artifact file's SHA-256). OpenSSL's libcrypto computes
// every MAC and digest; nothing here is hand-written crypto.
//
// Modes: kSigned (--key FILE): a message is taken when its tag verifies under its sender's key and its
// timestamp is fresh (AuthConfig) and after the sender's last one on that channel. kUnauthenticated (the
// explicit bench flag): every message is taken, as before signing existed. kEstopOnly (neither flag, the
// default): nothing is taken. estop is obeyed in every mode (safety rule R11, src/safety_supervisor.cpp).
// The robot's state (imu_t, joint_state_t) is verified by a second instance with the robot key (--robot-key):
// kSigned takes only the robot's frames, kUnauthenticated (no robot key, a bench) takes every one, and the
// supervisor's rule R12 then only tells a second sequence stream apart.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "t1/controller_status_t.hpp"
#include "t1_contract.hpp"

typedef struct evp_mac_ctx_st EVP_MAC_CTX;

namespace t1rt {

inline constexpr std::size_t kTagBytes = 32;  // tag_size of a signed runtime_cmd_t / joystick_t (0: unsigned)
inline constexpr std::size_t kKeyBytes = t1::kAuthKeyBytes;
inline constexpr std::size_t kMaxSenders = 16;  // lines of a key file
inline constexpr std::size_t kSha256Bytes = 32;

struct AuthConfig {
  double max_age_s = 2.0;   // a timestamp this much behind the runtime's wall clock is stale (a late replay)
  double max_lead_s = 2.0;  // this much ahead of it too (the sender's clock is off: synchronise it)
};

enum class AuthMode { kEstopOnly, kSigned, kUnauthenticated };

// Why a message was refused (controller_status_t.refused_*), in that order.
enum class Refusal : int { kNoKey, kUnsigned, kUnknownSender, kBadTag, kReplayed, kStale, kTagSize, kCount };
const char* refusal_text(Refusal r);

// The senders of a key file (messages/auth.py: "<sender_id> <64 hex digits>" lines, mode 0600). Immutable
// once loaded, so both threads may read it; the key bytes are wiped when it goes.
class KeyRing {
 public:
  ~KeyRing();
  // nullptr and *error when the file is missing, open to its group or others, malformed or empty.
  static std::shared_ptr<const KeyRing> load(const std::string& path, std::string* error);
  std::size_t size() const { return count_; }
  int64_t sender_id(std::size_t i) const { return senders_[i].id; }
  int index_of(int64_t sender_id) const;  // -1: not in the file
  const std::string& path() const { return path_; }
  // Keys an HMAC-SHA256 context with key i (CommandAuth's per-sender contexts).
  bool key_context(std::size_t i, EVP_MAC_CTX* ctx) const;
  // HMAC-SHA256(key i, head + body) -> out (one-shot; allocates inside OpenSSL: never on the loop).
  bool mac(std::size_t i, const void* head, std::size_t head_size, const void* body, std::size_t body_size,
           uint8_t out[kTagBytes]) const;
  // Signs an encoded runtime_cmd_t / joystick_t in place (encoded with tag_size kTagBytes): its last kTagBytes
  // become the tag over channel + NUL + the bytes before tag_size. false: not encoded with room for a tag.
  bool sign(std::size_t i, const char* channel, uint8_t* payload, std::size_t size) const;
  // m's encoding signed by sender i, with m's sender_id and timestamp_us as the caller set them (allocates:
  // tests, benches and peers, never the loop).
  template <class Message>
  std::vector<uint8_t> encode_signed(std::size_t i, const char* channel, Message m) const {
    m.tag_size = static_cast<int16_t>(kTagBytes);
    m.tag.assign(kTagBytes, 0);
    std::vector<uint8_t> out(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(out.data(), 0, static_cast<int>(out.size()));
    sign(i, channel, out.data(), out.size());
    return out;
  }
  // Whether `approvals` (messages/auth.py's approval lines) approves the file whose SHA-256 is `digest`;
  // false with *why naming what is missing or wrong.
  bool approves(const std::string& approvals, const uint8_t digest[kSha256Bytes], std::string* why) const;

 private:
  struct Entry {
    int64_t id = 0;
    std::array<uint8_t, kKeyBytes> key{};
  };
  std::array<Entry, kMaxSenders> senders_{};
  std::size_t count_ = 0;
  std::string path_;
};

// The loop's verifier: one keyed HMAC context per sender made at open(), so a verification allocates nothing
// of ours (OpenSSL 3.0 copies two digest states inside, 2 small allocations a message: counted by
// NoHeap.SignedJoystickAllocatesOnlyInsideOpenSSL). Loop thread only.
class CommandAuth {
 public:
  // Timestamps per channel: the operator's (runtime_cmd_t, joystick_t) and the robot's (imu_t, joint_state_t).
  enum Stream : int { kCommandStream = 0, kJoystickStream = 1, kImuStream = 2, kJointStream = 3, kStreams = 4 };
  CommandAuth() = default;
  ~CommandAuth();
  CommandAuth(const CommandAuth&) = delete;
  CommandAuth& operator=(const CommandAuth&) = delete;

  // keys: required for kSigned. false + *error if OpenSSL cannot key a context.
  bool open(AuthMode mode, std::shared_ptr<const KeyRing> keys, const AuthConfig& config, std::string* error);
  AuthMode mode() const { return mode_; }
  // The tag_size field of an encoded runtime_cmd_t (kCommandStream) / joystick_t (kJoystickStream), read
  // where the generated decoder reads it; false when the datagram ends before it. lcm-gen's C++ decoder sizes
  // the tag vector from this field before checking it against the datagram (a negative one throws, a large
  // one allocates), so only a datagram whose tag_size tag_size_ok() may be decoded.
  static bool read_tag_size(Stream stream, const uint8_t* payload, std::size_t size, int* tag_size);
  static bool tag_size_ok(int tag_size) { return tag_size == 0 || tag_size == static_cast<int>(kTagBytes); }
  // Counts a datagram whose tag_size is neither 0 nor kTagBytes (refused whatever its verb) and names it.
  void refuse_tag_size(const char* what, int tag_size);
  // One decoded datagram on a signed channel (its tag_size 0 or kTagBytes): whether it is the key holder's
  // (always under kUnauthenticated, never under kEstopOnly). A taken timestamp becomes the sender's last on
  // that stream.
  bool verify(Stream stream, const char* channel, const uint8_t* payload, std::size_t size, int64_t sender_id,
              int64_t timestamp_us, int tag_size);
  Refusal last_verdict() const { return verdict_; }
  // Counts the last verify()'s refusal and names it (`what`: e.g. "runtime_cmd_t set_mode passive").
  void refuse(const char* what, int64_t sender_id);
  int64_t refused(Refusal r) const { return refused_[static_cast<int>(r)]; }
  const char* last_refusal() const { return last_refusal_.data(); }  // "" until one
  const char* describe() const { return describe_.data(); }          // controller_status_t.command_auth
  // controller_status_t.command_auth and refused_* (its strings' capacity reserved: no allocation).
  void report(t1::controller_status_t& status) const;
  // The robot's verifier: controller_status_t.state_auth and state_refused_*.
  void report_state(t1::controller_status_t& status) const;
  int64_t refused_total() const;
  void set_description(const char* text);  // replaces describe() (the robot's verifier says "robot key")

 private:
  static int64_t wall_us();
  AuthMode mode_ = AuthMode::kEstopOnly;
  std::shared_ptr<const KeyRing> keys_;
  AuthConfig cfg_;
  std::array<EVP_MAC_CTX*, kMaxSenders> ctx_{};
  std::array<std::array<int64_t, kStreams>, kMaxSenders> last_us_{};
  int64_t start_us_ = 0;
  Refusal verdict_ = Refusal::kNoKey;
  double verdict_offset_s_ = 0.0;  // kStale: timestamp minus the wall clock [s]
  std::array<int64_t, static_cast<int>(Refusal::kCount)> refused_{};
  std::array<char, 200> last_refusal_{};
  std::array<char, 96> describe_{};
};

}  // namespace t1rt
