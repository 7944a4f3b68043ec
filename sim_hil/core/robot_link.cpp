#include "robot_link.hpp"

#include <openssl/core_names.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/params.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>

#include <t1/imu_t.hpp>
#include <t1/joint_command_t.hpp>
#include <t1/joint_state_t.hpp>
#include <t1_contract.hpp>
#include <t1_lcm_group.hpp>

namespace t1sim {
namespace {
constexpr int kReportedDrops = 5;      // drop reasons printed; the rest only counted (commands come at 500 Hz)
constexpr std::size_t kTagBytes = 32;  // messages/auth.py TAG_BYTES
constexpr std::size_t kSignedTail = 2 + kTagBytes;  // tag_size (int16) and the tag: what the tag does not cover
enum StateStream { kImuStream = 0, kJointStream = 1 };

int64_t wall_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

template <size_t N>
bool finite(const float (&v)[N]) {
  for (float x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

template <size_t N>
bool within(const float (&v)[N], float lo, float hi) {
  for (float x : v)
    if (x < lo || x > hi) return false;
  return true;
}
}  // namespace

RobotLink::RobotLink(const std::string& url)
    : tx_(t1::kLcmShortMaxPayloadBytes), sock_(t1::open_lcm_group_socket(url)), rx_(t1::kLcmMaxDatagramBytes) {
  sender_.open(url);
}

RobotLink::~RobotLink() {
  if (sock_ >= 0) close(sock_);
  EVP_MAC_CTX_free(mac_);
}

bool RobotLink::set_robot_key(int64_t sender_id, const uint8_t* key, std::size_t size) {
  static char digest[] = "SHA256";
  OSSL_PARAM params[] = {OSSL_PARAM_construct_utf8_string(OSSL_MAC_PARAM_DIGEST, digest, 0),
                         OSSL_PARAM_construct_end()};
  EVP_MAC* hmac = EVP_MAC_fetch(nullptr, "HMAC", nullptr);
  EVP_MAC_CTX* ctx = hmac ? EVP_MAC_CTX_new(hmac) : nullptr;
  EVP_MAC_free(hmac);  // the context holds its own reference
  if (!ctx || sender_id <= 0 || EVP_MAC_init(ctx, key, size, params) != 1) {
    EVP_MAC_CTX_free(ctx);
    return false;
  }
  EVP_MAC_CTX_free(mac_);
  mac_ = ctx;
  sender_id_ = sender_id;
  return true;
}

int RobotLink::handle_queued() {
  return t1::drain_lcm_group(sock_, rx_, [this](const t1::LcmDatagram& m) {
    if (std::strcmp(m.channel, t1::CH_JOINT_CMD) != 0) return;
    if (m.fragment) drop("T1_JOINT_CMD in fragments (over 64 kB: not a command)");
    else on_command(m.payload, m.size);
  });
}

void RobotLink::publish_state(const StateReading& s) {
  t1::imu_t imu{};
  imu.utime = s.utime_us;
  imu.seq = s.seq;
  for (int i = 0; i < 4; ++i) imu.quat[i] = static_cast<float>(s.quat[i]);
  for (int i = 0; i < 3; ++i) {
    imu.gyro[i] = static_cast<float>(s.gyro[i]);
    imu.accel[i] = static_cast<float>(s.accel[i]);
  }
  t1::joint_state_t js{};
  js.utime = s.utime_us;
  js.seq = s.seq;
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    js.q[i] = static_cast<float>(s.q[i]);
    js.dq[i] = static_cast<float>(s.dq[i]);
    js.tau_est[i] = static_cast<float>(s.tau[i]);
    js.motor_status[i] = s.status[i];
  }
  send(t1::CH_IMU, imu, kImuStream);
  send(t1::CH_JOINT_STATE, js, kJointStream);
}

template <class Message>
void RobotLink::send(const char* channel, Message& msg, int stream) {
  if (mac_) {  // messages/auth.py Signer.sign: the tag over channel + NUL + the encoding before tag_size
    int64_t& last = last_us_[static_cast<std::size_t>(stream)];
    last = std::max(wall_us(), last + 1);
    msg.sender_id = sender_id_;
    msg.timestamp_us = last;
    msg.tag_size = static_cast<int16_t>(kTagBytes);
    msg.tag.assign(kTagBytes, 0);
  }
  const int size = msg.encode(tx_.data(), 0, static_cast<int>(tx_.size()));
  if (size < 0) return;
  if (mac_) {
    uint8_t* tag = tx_.data() + size - kTagBytes;
    std::size_t n = 0;
    const bool ok = EVP_MAC_init(mac_, nullptr, 0, nullptr) &&
                    EVP_MAC_update(mac_, reinterpret_cast<const uint8_t*>(channel), std::strlen(channel) + 1) &&
                    EVP_MAC_update(mac_, tx_.data(), static_cast<std::size_t>(size) - kSignedTail) &&
                    EVP_MAC_final(mac_, tag, &n, kTagBytes) && n == kTagBytes;
    if (!ok) return;  // never sent with a wrong tag
  }
  sender_.send(channel, tx_.data(), static_cast<std::size_t>(size));
}

void RobotLink::drop(const std::string& reason) {
  ++dropped;
  last_drop_reason = reason;
  if (reported_ < kReportedDrops) {
    std::fprintf(stderr, "sim_hil: dropped command: %s\n", reason.c_str());
    ++reported_;
  }
}

void RobotLink::on_command(const uint8_t* payload, size_t size) {
  t1::joint_command_t c;
  if (c.decode(payload, 0, static_cast<int>(size)) < 0) return drop("undecodable T1_JOINT_CMD");
  const struct {
    const char* name;
    const float (&v)[T1_NUM_MOTORS];
  } fields[] = {{"q_des", c.q_des}, {"dq_des", c.dq_des}, {"kp", c.kp}, {"kd", c.kd}, {"tau_ff", c.tau_ff}};
  for (const auto& f : fields)
    if (!finite(f.v)) return drop(std::string(f.name) + " contains NaN or Inf");
  char why[96];
  if (!within(c.kp, 0.0f, T1_PROTOCOL.kp_max)) {
    std::snprintf(why, sizeof why, "kp outside [0, %g] N·m/rad", static_cast<double>(T1_PROTOCOL.kp_max));
    return drop(why);
  }
  if (!within(c.kd, 0.0f, T1_PROTOCOL.kd_max)) {
    std::snprintf(why, sizeof why, "kd outside [0, %g] N·m·s/rad", static_cast<double>(T1_PROTOCOL.kd_max));
    return drop(why);
  }
  double q[T1_NUM_MOTORS], dq[T1_NUM_MOTORS], kp[T1_NUM_MOTORS], kd[T1_NUM_MOTORS], tau[T1_NUM_MOTORS];
  for (unsigned i = 0; i < T1_NUM_MOTORS; ++i) {
    q[i] = c.q_des[i];
    dq[i] = c.dq_des[i];
    kp[i] = c.kp[i];
    kd[i] = c.kd[i];
    tau[i] = c.tau_ff[i];
  }
  (void)t1_batch_pack_commands(q, dq, kp, kd, tau, frames_);  // all finite: nothing left unpacked
  fresh_ = true;
  ++received;
  latest_state_seq_ = c.state_seq;
  latest_payload_.assign(payload, payload + size);
}

bool RobotLink::take_frames(uint8_t* out) {
  if (!fresh_) return false;
  std::memcpy(out, frames_, sizeof frames_);
  fresh_ = false;
  return true;
}

void RobotLink::poll(double timeout_s) {
  if (handle_queued() == 0 && t1::wait_readable(sock_, timeout_s)) handle_queued();
}

bool RobotLink::wait_for_answer(int64_t state_seq, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  handle_queued();
  while (!has_latest() || latest_state_seq_ < state_seq) {
    const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0.0) return false;
    if (t1::wait_readable(sock_, left)) handle_queued();
  }
  return true;
}

}  // namespace t1sim
