// Inputs the fuzz harnesses (runtime/fuzz) found, each through the code that failed on it; the same inputs are
// in the harnesses' seed corpora, so every fuzz pass replays them too.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <vector>

#include "t1/sim_status_t.hpp"
#include "t1_contract.hpp"
#include "t1_lcm_group.hpp"
#include "t1rt/transport.hpp"

namespace {

std::vector<uint8_t> datagram(const char* channel, const std::vector<uint8_t>& payload) {
  std::vector<uint8_t> d = {'L', 'C', '0', '2', 0, 0, 0, 1};
  d.insert(d.end(), channel, channel + std::strlen(channel) + 1);
  d.insert(d.end(), payload.begin(), payload.end());
  return d;
}

// A sim_status_t as the simulator sends it, with its scenario string's int32 length field replaced.
std::vector<uint8_t> sim_status_with_scenario_length(uint32_t length) {
  t1::sim_status_t m;
  m.scenario = "flat";
  m.clock = "lockstep";
  std::vector<uint8_t> payload(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(payload.data(), 0, static_cast<int>(payload.size()));
  constexpr std::size_t kScenarioLength = 3 * 8 + 4;  // after fingerprint, utime, step, real_time_factor
  for (int i = 0; i < 4; ++i) payload[kScenarioLength + i] = static_cast<uint8_t>(length >> (24 - 8 * i));
  return payload;
}

int deliver(t1rt::LcmTransport& transport, const std::vector<uint8_t>& payload) {
  const std::vector<uint8_t> d = datagram(t1::CH_SIM_STATUS, payload);
  t1::LcmDatagram m;
  if (!t1::parse_lcm_datagram(d.data(), d.size(), &m)) return -1;
  return transport.deliver(m);
}

}  // namespace

// fuzz_lcm_sim_status: a string length of INT32_MIN made lcm-gen's decoder compute length - 1 in int (signed
// overflow, UBSan) before it threw; now a length below 1 or past the datagram is a decode error, not decoded.
TEST(FuzzRegressions, SimStatusStringLengthBelowOneIsADecodeError) {
  t1rt::LcmTransport transport;
  transport.attach(t1rt::ClockMode::kLockstep, nullptr, nullptr, /*subscribe_sim_status=*/true,
                   /*subscribe_robot_state=*/false);
  for (uint32_t length : {0x80000000u, 0xFFFFFFFBu, 0u, 0x7FFFFFFFu}) {
    ASSERT_EQ(deliver(transport, sim_status_with_scenario_length(length)), 1);
    EXPECT_FALSE(transport.sim_status.have) << "length " << length;
  }
  EXPECT_EQ(transport.decode_errors, 4);
  ASSERT_EQ(deliver(transport, sim_status_with_scenario_length(5)), 1);  // "flat" + NUL: the real one
  EXPECT_TRUE(transport.sim_status.have);
  EXPECT_EQ(transport.sim_status.msg.scenario, "flat");
  EXPECT_EQ(transport.decode_errors, 4);
}
