// One rt/low_state writer (dds_transport.hpp): the runtime follows the writer of its first sample; a second
// writer's samples are refused and named by its GUID while the followed one is alive; after the followed one
// falls silent (the robot's stack restarted) the new writer is followed. Real Cyclone DDS inside tools/netns.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "t1_contract.hpp"
#include "t1rt/dds_transport.hpp"
#include "t1rt/periodic_task.hpp"

using namespace t1rt;

namespace {
constexpr double kWaitS = 10.0;  // bound on a delivery on loopback (not a timing check)
constexpr float kRobotQ = 0.1f, kForgedQ = 0.7f;

struct Writer {
  dds_entity_t participant = 0, writer = 0;
  explicit Writer(int domain) {
    participant = dds_create_participant(static_cast<dds_domainid_t>(domain), nullptr, nullptr);
    const dds_entity_t topic =
        dds_create_topic(participant, &booster_interface_msg_dds__LowState__desc, t1::kDdsStateTopic, nullptr, nullptr);
    writer = dds_create_writer(participant, topic, nullptr, nullptr);
  }
  ~Writer() { close(); }
  void close() {
    if (participant > 0) dds_delete(participant);
    participant = 0;
  }
  void write(float q) {
    std::vector<booster_interface_msg_dds__MotorState_> motors(kJoints);
    for (auto& m : motors) m.q = q;
    DdsLowState s{};
    s.imu_state.acc[2] = 9.81f;
    s.motor_state_serial._buffer = motors.data();
    s.motor_state_serial._length = s.motor_state_serial._maximum = static_cast<uint32_t>(kJoints);
    dds_write(writer, &s);
  }
};

struct Link {
  Supervisor sup;
  MessageSlot<t1::imu_t> imu;
  MessageSlot<t1::joint_state_t> joint;
  bool new_state = false;
  DdsTransport dds;
  bool ok = false;
  Link() {
    std::string error;
    ok = dds.open(t1::kDdsDomainId, ClockMode::kRealtime, &sup, &imu, &joint, &new_state, &error);
    EXPECT_TRUE(ok) << error;
  }
  // Writes q from w until something of it was taken or refused (discovery takes a moment).
  bool deliver(Writer& w, float q) {
    const int64_t taken = joint.received, refused = dds.other_writer_samples;
    const double end = monotonic_s() + kWaitS;
    while (monotonic_s() < end) {
      w.write(q);
      dds.wait(10);
      if (joint.received > taken || dds.other_writer_samples > refused) return true;
    }
    return false;
  }
};
}  // namespace

TEST(DdsOneWriter, ASecondWriterIsRefusedAndNamedAndARestartIsFollowed) {
  Link link;
  ASSERT_TRUE(link.ok);
  Writer robot(t1::kDdsDomainId), forger(t1::kDdsDomainId);
  ASSERT_TRUE(link.deliver(robot, kRobotQ));
  EXPECT_EQ(link.joint.msg.q[0], kRobotQ);
  const std::string followed = link.dds.followed.data();
  EXPECT_EQ(followed.size(), 32u) << followed;  // a 16-byte GUID in hex
  ASSERT_TRUE(link.deliver(forger, kForgedQ));
  robot.write(kRobotQ);  // the robot alive beside it
  link.dds.wait(10);
  EXPECT_GE(link.dds.other_writer_samples, 1);
  EXPECT_EQ(link.joint.msg.q[0], kRobotQ) << "a second writer's sample reached the state";
  const std::string named = link.dds.other_writer.data();
  EXPECT_NE(named.find("second writer"), std::string::npos) << named;
  EXPECT_EQ(named.find(followed), named.rfind(followed)) << named;  // following named once, the other apart
  // The robot's stack goes (its writer deleted) and is silent for the quiet time; a new writer is followed.
  robot.close();
  const double silent_from = monotonic_s();
  while (monotonic_s() - silent_from < SafetyConfig{}.restart_quiet_s) link.dds.wait(10);
  Writer restarted(t1::kDdsDomainId);
  const int64_t changes = link.dds.writer_changes;
  const double end = monotonic_s() + kWaitS;
  while (link.joint.msg.q[0] != kRobotQ * 2 && monotonic_s() < end) {
    restarted.write(kRobotQ * 2);
    link.dds.wait(10);
  }
  EXPECT_EQ(link.joint.msg.q[0], kRobotQ * 2) << link.dds.other_writer.data();
  EXPECT_EQ(link.dds.writer_changes, changes + 1);
  EXPECT_NE(std::string(link.dds.followed.data()), followed);
}
