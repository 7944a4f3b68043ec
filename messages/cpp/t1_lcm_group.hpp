// LCM's UDP multicast group read and written straight from sockets of one's own, for the peers on the tick's
// path (the simulator's core, the runtime). Why: the LCM library hands every datagram from a receive thread
// through a pipe, two wake-ups per message where the socket needs one; and its publish waits when the socket's
// send buffer is full (and, in C++, allocates a buffer per message), where a tick must drop and go on.
// Wire format (LCM's one-datagram message): "LC02" (big-endian magic), sequence number (4 bytes), the
// channel name with its NUL, the payload. Messages over one datagram ("LC03" fragments: a 20-byte header, the
// channel in the first piece only) are recognised, not reassembled: no channel on the tick's path needs them.
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace t1 {

inline constexpr uint32_t kLcmShortMagic = 0x4C433032;      // "LC02": a whole message in one datagram
inline constexpr uint32_t kLcmFragmentMagic = 0x4C433033;   // "LC03": a piece of a larger message
inline constexpr std::size_t kLcmHeaderBytes = 8;            // magic, sequence number
inline constexpr std::size_t kLcmFragmentHeaderBytes = 20;   // + size, offset, piece number, pieces
inline constexpr std::size_t kLcmMaxDatagramBytes = 65536;
inline constexpr int kLcmGroupReceiveBufferBytes = 1 << 21;  // a slow tick must not lose a message to a full buffer

inline constexpr std::size_t kLcmMaxChannelBytes = 255;      // LCM's longest channel name
inline constexpr std::size_t kLcmShortMaxPayloadBytes = 65499 - kLcmHeaderBytes - kLcmMaxChannelBytes - 1;

struct UdpmAddress {
  in_addr group{};
  int port = 0;
  int ttl = 0;   // LCM's ttl option (default 0: this host only)
};

// udpm://GROUP:PORT[?options] (LCM's URL) → the group, port and ttl; false if the URL is not one.
inline bool parse_udpm_url(const std::string& url, UdpmAddress* out) {
  const std::string scheme = "udpm://";
  if (url.compare(0, scheme.size(), scheme) != 0) return false;
  const auto colon = url.find(':', scheme.size());
  if (colon == std::string::npos) return false;
  const std::string group = url.substr(scheme.size(), colon - scheme.size());
  out->port = std::atoi(url.c_str() + colon + 1);
  const auto ttl = url.find("ttl=", colon);
  out->ttl = ttl == std::string::npos ? 0 : std::atoi(url.c_str() + ttl + 4);
  return out->port > 0 && out->port < 65536 && out->ttl >= 0 && out->ttl < 256 &&
         inet_aton(group.c_str(), &out->group) != 0;
}

// udpm://GROUP:PORT[?options] → a non-blocking socket on the group's port, joined to the group, asking for
// receive_buffer_bytes of kernel buffer (-1 if the URL is not udpm or the socket cannot be set up). All peers
// bind the port, as LCM does (SO_REUSEADDR).
inline int open_lcm_group_socket(const std::string& url, int receive_buffer_bytes = kLcmGroupReceiveBufferBytes) {
  UdpmAddress where;
  if (!parse_udpm_url(url, &where)) return -1;
  const int fd = socket(AF_INET, SOCK_DGRAM, IPPROTO_UDP);
  if (fd < 0) return -1;
  const int one = 1, rcvbuf = receive_buffer_bytes;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(where.port));
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  ip_mreq mreq{};
  mreq.imr_multiaddr = where.group;
  const bool ok = setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) == 0 &&
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

// Whether fd became readable within timeout_s [s] (to the microsecond; false at once for timeout_s <= 0).
inline bool wait_readable(int fd, double timeout_s) {
  if (timeout_s <= 0.0) return false;
  fd_set fds;
  FD_ZERO(&fds);
  FD_SET(fd, &fds);
  const auto us = static_cast<long>(timeout_s * 1e6);
  timeval tv{us / 1000000L, us % 1000000L};
  return select(fd + 1, &fds, nullptr, nullptr, &tv) > 0;
}

struct LcmDatagram {
  const char* channel = nullptr;   // NUL-terminated, inside the datagram (a fragment's: first piece only)
  const uint8_t* payload = nullptr;   // a whole message's (unset for a fragment)
  std::size_t size = 0;
  bool fragment = false;           // an "LC03" piece of a larger message
};

// One received datagram → its channel and payload; false if it is not an LCM datagram.
inline bool parse_lcm_datagram(const uint8_t* buf, std::size_t n, LcmDatagram* out) {
  *out = LcmDatagram{};
  if (n < kLcmHeaderBytes) return false;
  const uint32_t magic = (uint32_t{buf[0]} << 24) | (uint32_t{buf[1]} << 16) | (uint32_t{buf[2]} << 8) | buf[3];
  out->fragment = magic == kLcmFragmentMagic;
  if (!out->fragment && magic != kLcmShortMagic) return false;
  const std::size_t header = out->fragment ? kLcmFragmentHeaderBytes : kLcmHeaderBytes;
  const bool named = !out->fragment || (n >= header && buf[16] == 0 && buf[17] == 0);   // piece number 0
  if (n < header || !named) return out->fragment;
  const auto* name = reinterpret_cast<const char*>(buf + header);
  const auto* end = static_cast<const char*>(std::memchr(name, '\0', n - header));
  if (end == nullptr) return false;
  out->channel = name;
  if (!out->fragment) {
    out->payload = reinterpret_cast<const uint8_t*>(end + 1);
    out->size = n - static_cast<std::size_t>(out->payload - buf);
  }
  return true;
}

// Reads every datagram queued on fd into rx, without waiting, and hands each LCM one that names its channel
// (a whole message, or a fragment's first piece) to on_datagram(const LcmDatagram&); how many it read.
template <class OnDatagram>
int drain_lcm_group(int fd, std::vector<uint8_t>& rx, OnDatagram&& on_datagram) {
  int read = 0;
  for (;;) {
    const ssize_t got = recv(fd, rx.data(), rx.size(), MSG_DONTWAIT);
    if (got < 0) return read;
    ++read;
    LcmDatagram m;
    if (parse_lcm_datagram(rx.data(), static_cast<std::size_t>(got), &m) && m.channel != nullptr) on_datagram(m);
  }
}

// Publishing to the group from a socket of one's own, never waiting: each message is one "LC02" datagram sent
// with MSG_DONTWAIT from the caller's buffer (header and payload gathered, no copy, no allocation). A message
// the kernel cannot take at once (send buffer full) is dropped and counted: the tick goes on. Multicast TTL from
// the URL's ttl option, looped back to this host's peers, as LCM's own publisher.
class LcmGroupSender {
 public:
  LcmGroupSender() = default;
  ~LcmGroupSender() { if (fd_ >= 0) close(fd_); }
  LcmGroupSender(const LcmGroupSender&) = delete;
  LcmGroupSender& operator=(const LcmGroupSender&) = delete;

  // false if the URL is not udpm://GROUP:PORT[?ttl=N] or the group cannot be reached (no multicast route).
  bool open(const std::string& url) {
    UdpmAddress where;
    if (fd_ >= 0 || !parse_udpm_url(url, &where)) return false;
    fd_ = socket(AF_INET, SOCK_DGRAM, IPPROTO_UDP);
    if (fd_ < 0) return false;
    const unsigned char ttl = static_cast<unsigned char>(where.ttl), loop = 1;
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<uint16_t>(where.port));
    to.sin_addr = where.group;
    const bool ok = setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl) == 0 &&
                    setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop) == 0 &&
                    connect(fd_, reinterpret_cast<sockaddr*>(&to), sizeof to) == 0;
    if (!ok) {
      close(fd_);
      fd_ = -1;
    }
    return ok;
  }
  bool good() const { return fd_ >= 0; }

  // One message on `channel`; false (and counted in dropped) if it was not sent whole at once.
  bool send(const char* channel, const void* payload, std::size_t size) {
    const std::size_t name = std::strlen(channel);
    if (fd_ < 0 || name > kLcmMaxChannelBytes || size > kLcmShortMaxPayloadBytes) return count_drop();
    const uint32_t words[2] = {htonl(kLcmShortMagic), htonl(seq_++)};
    std::memcpy(header_.data(), words, sizeof words);
    std::memcpy(header_.data() + kLcmHeaderBytes, channel, name + 1);
    iovec parts[2] = {{header_.data(), kLcmHeaderBytes + name + 1}, {const_cast<void*>(payload), size}};
    msghdr msg{};
    msg.msg_iov = parts;
    msg.msg_iovlen = 2;
    const ssize_t sent = sendmsg(fd_, &msg, MSG_DONTWAIT);
    if (sent != static_cast<ssize_t>(parts[0].iov_len + size)) return count_drop();
    return true;
  }

  uint64_t dropped = 0;   // messages not sent (send buffer full, no route, too large)

 private:
  bool count_drop() {
    ++dropped;
    return false;
  }
  int fd_ = -1;
  uint32_t seq_ = 0;
  std::array<uint8_t, kLcmHeaderBytes + kLcmMaxChannelBytes + 1> header_{};
};

}  // namespace t1
