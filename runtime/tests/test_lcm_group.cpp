// The LCM group's own sockets (messages/cpp/t1_lcm_group.hpp) as the runtime opens them: URLs read as LCM reads
// them, and the non-blocking sender's datagrams as the group's readers parse them (inside tools/netns).
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>
#include <vector>

#include "t1_lcm_group.hpp"
#include "t1rt/transport.hpp"

namespace t1rt {
namespace {

// The transport receives on its own socket on the LCM group: a URL that names none is refused, naming the URL.
TEST(LcmTransportOpen, UrlWithoutAMulticastGroupRefused) {
  for (const char* url : {"memq://", "udpm://239.255.76.67", "udpm://not-an-address:7667"}) {
    LcmTransport transport;
    std::string error;
    EXPECT_FALSE(transport.open(url, ClockMode::kLockstep, nullptr, nullptr, &error)) << url;
    EXPECT_NE(error.find(std::string("'") + url + "'"), std::string::npos) << error;
  }
}

// The group's URL as LCM reads it: group, port, ttl (default 0: this host only).
TEST(LcmGroupSender, UdpmUrlsParsedAsLcmDoes) {
  t1::UdpmAddress a;
  ASSERT_TRUE(t1::parse_udpm_url("udpm://239.255.76.67:7667", &a));
  EXPECT_EQ(a.port, 7667);
  EXPECT_EQ(a.ttl, 0);
  ASSERT_TRUE(t1::parse_udpm_url("udpm://239.255.76.67:7700?recv_buf_size=4096&ttl=1", &a));
  EXPECT_EQ(a.port, 7700);
  EXPECT_EQ(a.ttl, 1);
  for (const char* url : {"memq://", "udpm://239.255.76.67", "udpm://not-an-address:7667", "udpm://239.1.1.1:0",
                          "udpm://239.1.1.1:7667?ttl=300"})
    EXPECT_FALSE(t1::parse_udpm_url(url, &a)) << url;
}

// What the sender puts on the group is one LCM datagram (channel, payload) that the group's readers parse; a
// payload over one datagram is not sent, and counted.
TEST(LcmGroupSender, SendsOneLcmDatagramWithoutWaiting) {
  const std::string url = resolve_lcm_url("");
  const int rx = t1::open_lcm_group_socket(url);
  ASSERT_GE(rx, 0) << "run inside tools/netns";
  t1::LcmGroupSender sender;
  ASSERT_TRUE(sender.open(url));
  const std::vector<uint8_t> payload = {1, 2, 3, 250};
  ASSERT_TRUE(sender.send("T1_SENDER_TEST", payload.data(), payload.size()));
  std::vector<uint8_t> got, buf(t1::kLcmMaxDatagramBytes);
  for (int tries = 0; tries < 100 && got.empty(); ++tries) {
    t1::wait_readable(rx, 0.01);
    t1::drain_lcm_group(rx, buf, [&](const t1::LcmDatagram& m) {
      if (std::string(m.channel) == "T1_SENDER_TEST") got.assign(m.payload, m.payload + m.size);
    });
  }
  close(rx);
  EXPECT_EQ(got, payload);
  EXPECT_EQ(sender.dropped, 0u);
  const std::vector<uint8_t> huge(t1::kLcmShortMaxPayloadBytes + 1);
  EXPECT_FALSE(sender.send("T1_SENDER_TEST", huge.data(), huge.size()));
  EXPECT_EQ(sender.dropped, 1u);
  t1::LcmGroupSender unopened;
  EXPECT_FALSE(unopened.send("T1_SENDER_TEST", payload.data(), payload.size()));
}

}  // namespace
}  // namespace t1rt
