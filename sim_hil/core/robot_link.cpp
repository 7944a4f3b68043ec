#include "robot_link.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <t1/imu_t.hpp>
#include <t1/joint_command_t.hpp>
#include <t1/joint_state_t.hpp>
#include <t1_contract.hpp>

namespace t1sim {
namespace {
constexpr int kReportedDrops = 5;   // drop reasons printed; the rest only counted (commands come at 500 Hz)
constexpr double kUsPerS = 1e6;
constexpr uint32_t kShortMagic = 0x4C433032;   // "LC02": a message in one datagram
constexpr size_t kHeaderBytes = 8;             // magic, sequence number
constexpr size_t kMaxDatagramBytes = 65536;
constexpr int kReceiveBufferBytes = 1 << 21;   // a slow tick must not cost a command to a full buffer

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

// udpm://GROUP:PORT[?options] → the socket that receives the group's datagrams (-1 if it cannot).
static int open_group_socket(const std::string& url) {
  const std::string scheme = "udpm://";
  if (url.compare(0, scheme.size(), scheme) != 0) return -1;
  const auto colon = url.find(':', scheme.size());
  if (colon == std::string::npos) return -1;
  const std::string group = url.substr(scheme.size(), colon - scheme.size());
  const int port = std::atoi(url.c_str() + colon + 1);
  const int fd = socket(AF_INET, SOCK_DGRAM, IPPROTO_UDP);
  if (fd < 0) return -1;
  const int one = 1, rcvbuf = kReceiveBufferBytes;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(port));
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  ip_mreq mreq{};
  const bool ok = port > 0 && inet_aton(group.c_str(), &mreq.imr_multiaddr) != 0 &&
                  setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) == 0 &&   // as LCM: all peers bind it
                  setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf) == 0 &&
                  bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
                  setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mreq, sizeof mreq) == 0 &&
                  fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK) == 0;
  if (!ok) {
    close(fd);
    return -1;
  }
  return fd;
}

RobotLink::RobotLink(const std::string& url) : lcm_(url), sock_(open_group_socket(url)), rx_(kMaxDatagramBytes) {}

RobotLink::~RobotLink() {
  if (sock_ >= 0) close(sock_);
}

int RobotLink::handle_queued() {
  uint8_t* buf = rx_.data();
  const size_t name_len = std::strlen(t1::CH_JOINT_CMD) + 1;   // with its NUL
  int n = 0;
  for (;;) {
    const ssize_t got = recv(sock_, buf, rx_.size(), 0);
    if (got < 0) return n;
    ++n;
    const auto size = static_cast<size_t>(got);
    if (size < kHeaderBytes + name_len || std::memcmp(buf + kHeaderBytes, t1::CH_JOINT_CMD, name_len) != 0) continue;
    const uint32_t magic = (uint32_t{buf[0]} << 24) | (uint32_t{buf[1]} << 16) | (uint32_t{buf[2]} << 8) | buf[3];
    if (magic != kShortMagic) {   // a fragmented message (> 64 kB): never a command
      drop("T1_JOINT_CMD in fragments (not a command)");
      continue;
    }
    on_command(buf + kHeaderBytes + name_len, size - kHeaderBytes - name_len);
  }
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
  lcm_.publish(t1::CH_IMU, &imu);
  lcm_.publish(t1::CH_JOINT_STATE, &js);
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
  const struct { const char* name; const float (&v)[T1_NUM_MOTORS]; } fields[] = {
      {"q_des", c.q_des}, {"dq_des", c.dq_des}, {"kp", c.kp}, {"kd", c.kd}, {"tau_ff", c.tau_ff}};
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
  (void)t1_batch_pack_commands(q, dq, kp, kd, tau, frames_);   // all finite: nothing left unpacked
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

bool RobotLink::wait_readable(double timeout_s) {
  if (timeout_s <= 0.0) return false;
  const int fd = sock_;
  fd_set fds;
  FD_ZERO(&fds);
  FD_SET(fd, &fds);
  const auto us = static_cast<long>(timeout_s * kUsPerS);
  timeval tv{us / 1000000L, us % 1000000L};
  return select(fd + 1, &fds, nullptr, nullptr, &tv) > 0;
}

void RobotLink::poll(double timeout_s) {
  if (handle_queued() == 0 && wait_readable(timeout_s)) handle_queued();
}

bool RobotLink::wait_for_answer(int64_t state_seq, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  handle_queued();
  while (!has_latest() || latest_state_seq_ < state_seq) {
    const double left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0.0) return false;
    if (wait_readable(left)) handle_queued();
  }
  return true;
}

}  // namespace t1sim
