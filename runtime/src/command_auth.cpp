// The runtime's side of messages/auth.py: key files, tag verification, freshness, approvals (command_auth.hpp).
#include "t1rt/command_auth.hpp"

#include "t1/imu_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1/joystick_t.hpp"

#include <fcntl.h>
#include <openssl/core_names.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/params.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>

namespace t1rt {

namespace {
constexpr double kUsToS = 1e-6;
constexpr double kSToUs = 1e6;
constexpr std::size_t kTagSizeBytes = sizeof(int16_t);               // the tag_size field
constexpr std::size_t kSignedTailBytes = kTagSizeBytes + kTagBytes;  // what the tag does not cover

uint32_t big_endian(const uint8_t* p, std::size_t n) {
  uint32_t v = 0;
  for (std::size_t i = 0; i < n; ++i) v = v << 8 | p[i];
  return v;
}

// Where lcm-gen's decoder reads tag_size: after the 8-byte fingerprint and the fields before it
// (messages/t1/*.lcm; held to the generated encoding by CommandAuth.ReadsTagSizeWhereTheDecoderDoes). false:
// the datagram ends first, or a string length the decoder would take for a negative size (an LCM string's
// length counts its NUL, so it is at least 1).
bool tag_size_offset(CommandAuth::Stream stream, const uint8_t* p, std::size_t size, std::size_t* offset) {
  // Fixed-size fields only (joystick_t, imu_t, joint_state_t): a default message's encoding, tag_size last.
  static const std::size_t joystick = static_cast<std::size_t>(t1::joystick_t{}.getEncodedSize()) - kTagSizeBytes;
  static const std::size_t imu = static_cast<std::size_t>(t1::imu_t{}.getEncodedSize()) - kTagSizeBytes;
  static const std::size_t joint = static_cast<std::size_t>(t1::joint_state_t{}.getEncodedSize()) - kTagSizeBytes;
  switch (stream) {
    case CommandAuth::kJoystickStream:
      *offset = joystick;
      return true;
    case CommandAuth::kImuStream:
      *offset = imu;
      return true;
    case CommandAuth::kJointStream:
      *offset = joint;
      return true;
    default:
      break;
  }
  // runtime_cmd_t: fingerprint, utime, seq; verb, argument (int32 length, bytes, NUL); sender_id, timestamp_us
  constexpr std::size_t kHead = 3 * sizeof(int64_t), kLength = sizeof(int32_t), kStrings = 2;
  constexpr std::size_t kTail = 2 * sizeof(int64_t);
  std::size_t pos = kHead;
  for (std::size_t s = 0; s < kStrings; ++s) {
    if (size < pos + kLength) return false;
    const uint32_t length = big_endian(p + pos, kLength);
    pos += kLength;
    if (length < 1 || length > size - pos) return false;
    pos += length;
  }
  *offset = pos + kTail;
  return true;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// Whole-string hex of exactly n bytes.
bool parse_hex(const std::string& text, uint8_t* out, std::size_t n) {
  if (text.size() != 2 * n) return false;
  for (std::size_t i = 0; i < n; ++i) {
    const int hi = hex_value(text[2 * i]), lo = hex_value(text[2 * i + 1]);
    if (hi < 0 || lo < 0) return false;
    out[i] = static_cast<uint8_t>(hi << 4 | lo);
  }
  return true;
}

bool parse_sender_id(const std::string& text, int64_t* out) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end || errno == ERANGE || v <= 0) return false;
  *out = v;
  return true;
}

OSSL_PARAM* sha256_params() {
  static char digest[] = "SHA256";
  static OSSL_PARAM params[] = {OSSL_PARAM_construct_utf8_string(OSSL_MAC_PARAM_DIGEST, digest, 0),
                                OSSL_PARAM_construct_end()};
  return params;
}

// OpenSSL's HMAC, fetched once (a fetch looks the algorithm up in the provider store: the costly part of a
// one-shot MAC); an EVP_MAC is reference counted and may be shared between threads.
EVP_MAC* hmac_algorithm() {
  static EVP_MAC* const alg = EVP_MAC_fetch(nullptr, "HMAC", nullptr);
  return alg;
}

std::string line_of(const std::string& path, int number) { return path + " line " + std::to_string(number); }
}  // namespace

const char* refusal_text(Refusal r) {
  switch (r) {
    case Refusal::kNoKey:
      return "the runtime has no --key: it takes estop only";
    case Refusal::kUnsigned:
      return "unsigned (tag_size 0 or sender_id 0)";
    case Refusal::kUnknownSender:
      return "sender not in the key file";
    case Refusal::kBadTag:
      return "tag does not verify (another key, or bytes altered)";
    case Refusal::kReplayed:
      return "replayed (timestamp not after the sender's last)";
    case Refusal::kStale:
      return "stale timestamp";
    case Refusal::kTagSize:
      return "tag_size neither 0 (unsigned) nor 32 (signed)";
    case Refusal::kCount:
      break;
  }
  return "?";
}

// ------------------------------------------------------------------------------------------------ KeyRing
// The keys live in this process's memory as long as it runs (its HMAC contexts hold them too); the ring's own
// copy is wiped when the ring goes.
KeyRing::~KeyRing() { OPENSSL_cleanse(senders_.data(), sizeof(senders_)); }

std::shared_ptr<const KeyRing> KeyRing::load(const std::string& path, std::string* error) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    *error = "key file " + path + ": " + std::strerror(errno);
    return nullptr;
  }
  struct stat st {};
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || (st.st_mode & (S_IRWXG | S_IRWXO))) {
    ::close(fd);
    char mode[16];
    std::snprintf(mode, sizeof(mode), "%03o", static_cast<unsigned>(st.st_mode & 0777));
    *error = "key file " + path + ": not a regular file of mode 600 (mode " + mode +
             " lets its group or others at the key): chmod 600 " + path;
    return nullptr;
  }
  std::string text;
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof(buf))) > 0;) text.append(buf, static_cast<std::size_t>(n));
  ::close(fd);
  auto ring = std::shared_ptr<KeyRing>(new KeyRing());
  ring->path_ = path;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    line = line.substr(0, line.find('#'));
    std::istringstream words(line);
    std::string id_text, key_text, extra;
    if (!(words >> id_text)) continue;
    Entry e;
    if (!(words >> key_text) || (words >> extra) || !parse_sender_id(id_text, &e.id) ||
        !parse_hex(key_text, e.key.data(), kKeyBytes)) {
      *error = "key file " + line_of(path, number) +
               ": expected '<sender_id > 0> <key: " + std::to_string(2 * kKeyBytes) + " hex digits>'";
      return nullptr;
    }
    if (ring->index_of(e.id) >= 0) {
      *error = "key file " + line_of(path, number) + ": sender " + id_text + " listed twice";
      return nullptr;
    }
    if (ring->count_ == kMaxSenders) {
      *error = "key file " + path + ": more than " + std::to_string(kMaxSenders) + " senders";
      return nullptr;
    }
    ring->senders_[ring->count_++] = e;
  }
  if (ring->count_ == 0) {
    *error = "key file " + path + ": no sender line";
    return nullptr;
  }
  return ring;
}

int KeyRing::index_of(int64_t sender_id) const {
  for (std::size_t i = 0; i < count_; ++i)
    if (senders_[i].id == sender_id) return static_cast<int>(i);
  return -1;
}

bool KeyRing::key_context(std::size_t i, EVP_MAC_CTX* ctx) const {
  return EVP_MAC_init(ctx, senders_[i].key.data(), kKeyBytes, sha256_params()) == 1;
}

bool KeyRing::mac(std::size_t i, const void* head, std::size_t head_size, const void* body, std::size_t body_size,
                  uint8_t out[kTagBytes]) const {
  EVP_MAC_CTX* ctx = hmac_algorithm() ? EVP_MAC_CTX_new(hmac_algorithm()) : nullptr;
  std::size_t n = 0;
  const bool ok = ctx && key_context(i, ctx) && EVP_MAC_update(ctx, static_cast<const uint8_t*>(head), head_size) &&
                  EVP_MAC_update(ctx, static_cast<const uint8_t*>(body), body_size) &&
                  EVP_MAC_final(ctx, out, &n, kTagBytes) && n == kTagBytes;
  EVP_MAC_CTX_free(ctx);
  return ok;
}

bool KeyRing::sign(std::size_t i, const char* channel, uint8_t* payload, std::size_t size) const {
  if (size < kSignedTailBytes || big_endian(payload + size - kSignedTailBytes, kTagSizeBytes) != kTagBytes)
    return false;
  return mac(i, channel, std::strlen(channel) + 1, payload, size - kSignedTailBytes, payload + size - kTagBytes);
}

bool KeyRing::approves(const std::string& approvals, const uint8_t digest[kSha256Bytes], std::string* why) const {
  std::ifstream in(approvals);
  char hex[2 * kSha256Bytes + 1];
  for (std::size_t i = 0; i < kSha256Bytes; ++i) std::snprintf(hex + 2 * i, 3, "%02x", digest[i]);
  if (!in) {
    *why = "no approvals file " + approvals + " (approve the artifact: tools/t1key approve --key KEY --approvals " +
           approvals + " ARTIFACT)";
    return false;
  }
  const std::string context = std::string(t1::kApprovalContext) + '\0';
  std::string line, unverified;
  for (int number = 1; std::getline(in, line); ++number) {
    std::istringstream words(line.substr(0, line.find('#')));
    std::string sha, id_text, tag_text;
    if (!(words >> sha >> id_text >> tag_text) || sha != hex) continue;
    int64_t id = 0;
    uint8_t tag[kTagBytes], want[kTagBytes];
    const int k = parse_sender_id(id_text, &id) ? index_of(id) : -1;
    if (k < 0 || !parse_hex(tag_text, tag, kTagBytes) ||
        !mac(static_cast<std::size_t>(k), context.data(), context.size(), digest, kSha256Bytes, want) ||
        CRYPTO_memcmp(tag, want, kTagBytes) != 0) {
      unverified = line_of(approvals, number) + " (sender " + id_text + ")";
      continue;
    }
    return true;
  }
  *why = unverified.empty()
             ? "content sha256 " + std::string(hex) + " is not approved (no line for it in " + approvals + ")"
             : "the approval of sha256 " + std::string(hex) + " in " + unverified +
                   " does not verify under the key file's keys";
  return false;
}

// ------------------------------------------------------------------------------------------------ CommandAuth
CommandAuth::~CommandAuth() {
  for (EVP_MAC_CTX* c : ctx_) EVP_MAC_CTX_free(c);
}

int64_t CommandAuth::wall_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

bool CommandAuth::open(AuthMode mode, std::shared_ptr<const KeyRing> keys, const AuthConfig& config,
                       std::string* error) {
  mode_ = mode;
  keys_ = std::move(keys);
  cfg_ = config;
  start_us_ = wall_us();
  if (mode_ == AuthMode::kSigned) {
    if (!keys_) {
      *error = "signed commands need a key file";
      return false;
    }
    // The keyed context of each sender; verify() re-initialises it with the same key (EVP_MAC_init, no key).
    bool ok = hmac_algorithm() != nullptr;
    for (std::size_t i = 0; ok && i < keys_->size(); ++i) {
      ctx_[i] = EVP_MAC_CTX_new(hmac_algorithm());
      ok = ctx_[i] && keys_->key_context(i, ctx_[i]);
    }
    if (!ok) {
      *error = "OpenSSL could not key an HMAC-SHA256 context";
      return false;
    }
  }
  const char* text = mode_ == AuthMode::kUnauthenticated ? "unauthenticated"
                     : mode_ == AuthMode::kEstopOnly     ? "estop only (no --key)"
                                                         : nullptr;
  if (text) std::snprintf(describe_.data(), describe_.size(), "%s", text);
  else std::snprintf(describe_.data(), describe_.size(), "signed (%zu senders)", keys_->size());
  return true;
}

bool CommandAuth::read_tag_size(Stream stream, const uint8_t* payload, std::size_t size, int* tag_size) {
  std::size_t at = 0;
  if (!tag_size_offset(stream, payload, size, &at) || size < at + kTagSizeBytes) return false;
  *tag_size = static_cast<int16_t>(big_endian(payload + at, kTagSizeBytes));
  return true;
}

bool CommandAuth::verify(Stream stream, const char* channel, const uint8_t* payload, std::size_t size,
                         int64_t sender_id, int64_t timestamp_us, int tag_size) {
  if (mode_ == AuthMode::kUnauthenticated) return true;
  verdict_ = Refusal::kNoKey;
  if (mode_ == AuthMode::kEstopOnly) return false;
  verdict_ = Refusal::kUnsigned;
  if (sender_id == 0 || tag_size != static_cast<int>(kTagBytes) || size < kSignedTailBytes) return false;
  verdict_ = Refusal::kUnknownSender;
  const int i = keys_->index_of(sender_id);
  if (i < 0) return false;
  // The tag first: an unverified message may neither advance nor be told apart by its timestamp.
  EVP_MAC_CTX* ctx = ctx_[static_cast<std::size_t>(i)];
  uint8_t want[kTagBytes];
  std::size_t n = 0;
  const bool mac_ok = EVP_MAC_init(ctx, nullptr, 0, nullptr) &&
                      EVP_MAC_update(ctx, reinterpret_cast<const uint8_t*>(channel), std::strlen(channel) + 1) &&
                      EVP_MAC_update(ctx, payload, size - kSignedTailBytes) && EVP_MAC_final(ctx, want, &n, kTagBytes);
  verdict_ = Refusal::kBadTag;
  if (!mac_ok || n != kTagBytes || CRYPTO_memcmp(want, payload + size - kTagBytes, kTagBytes) != 0) return false;
  // Fresh (within the window, not before this runtime started: no replay of an older run's bytes), then
  // after the sender's last on this stream (no replay within the window).
  const int64_t now = wall_us();
  verdict_offset_s_ = static_cast<double>(timestamp_us - now) * kUsToS;
  verdict_ = Refusal::kStale;
  if (timestamp_us < start_us_ || timestamp_us < now - static_cast<int64_t>(cfg_.max_age_s * kSToUs) ||
      timestamp_us > now + static_cast<int64_t>(cfg_.max_lead_s * kSToUs))
    return false;
  int64_t& last = last_us_[static_cast<std::size_t>(i)][stream];
  verdict_ = Refusal::kReplayed;
  if (timestamp_us <= last) return false;
  last = timestamp_us;
  return true;
}

void CommandAuth::report(t1::controller_status_t& s) const {
  s.command_auth.assign(describe_.data(), std::min(std::strlen(describe_.data()), s.command_auth.capacity()));
  s.refused_no_key = refused(Refusal::kNoKey);
  s.refused_unsigned = refused(Refusal::kUnsigned);
  s.refused_unknown_sender = refused(Refusal::kUnknownSender);
  s.refused_bad_tag = refused(Refusal::kBadTag);
  s.refused_replayed = refused(Refusal::kReplayed);
  s.refused_stale = refused(Refusal::kStale);
  s.refused_tag_size = refused(Refusal::kTagSize);
}

void CommandAuth::report_state(t1::controller_status_t& s) const {
  s.state_auth.assign(describe_.data(), std::min(std::strlen(describe_.data()), s.state_auth.capacity()));
  s.state_refused_unsigned = refused(Refusal::kUnsigned);
  s.state_refused_unknown_sender = refused(Refusal::kUnknownSender);
  s.state_refused_bad_tag = refused(Refusal::kBadTag);
  s.state_refused_replayed = refused(Refusal::kReplayed);
  s.state_refused_stale = refused(Refusal::kStale);
  s.state_refused_tag_size = refused(Refusal::kTagSize);
}

int64_t CommandAuth::refused_total() const {
  int64_t n = 0;
  for (int64_t r : refused_) n += r;
  return n;
}

void CommandAuth::set_description(const char* text) { std::snprintf(describe_.data(), describe_.size(), "%s", text); }

void CommandAuth::refuse_tag_size(const char* what, int tag_size) {
  verdict_ = Refusal::kTagSize;
  ++refused_[static_cast<int>(verdict_)];
  std::snprintf(last_refusal_.data(), last_refusal_.size(),
                "refused %s: tag_size %d, neither 0 (unsigned) nor %zu "
                "(signed)",
                what, tag_size, kTagBytes);
}

void CommandAuth::refuse(const char* what, int64_t sender_id) {
  ++refused_[static_cast<int>(verdict_)];
  if (verdict_ == Refusal::kStale)
    std::snprintf(last_refusal_.data(), last_refusal_.size(),
                  "refused %s from sender %" PRId64
                  ": stale timestamp "
                  "(%+.3f s from this clock, window -%.1f..+%.1f s, none before the runtime's start)",
                  what, sender_id, verdict_offset_s_, cfg_.max_age_s, cfg_.max_lead_s);
  else
    std::snprintf(last_refusal_.data(), last_refusal_.size(), "refused %s from sender %" PRId64 ": %s", what, sender_id,
                  refusal_text(verdict_));
}

}  // namespace t1rt
