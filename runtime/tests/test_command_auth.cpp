// Who may command (command_auth.hpp) and the policy folder (policy_store.hpp), without a network: the golden
// vector of messages/auth.py, the key file's checks, every refusal reason, and load_policy's path and approval
// rules. Out of process, as an outside program tries them: tests/test_runtime_auth.py.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "t1/imu_t.hpp"
#include "t1/joint_state_t.hpp"
#include "t1/joystick_t.hpp"
#include "t1/runtime_cmd_t.hpp"
#include "t1rt/command_auth.hpp"
#include "t1rt/policy_store.hpp"
#include "test_artifact.hpp"
#include "test_keys.hpp"

using namespace t1rt;
using namespace t1rt::testing;

namespace {
std::vector<uint8_t> from_hex(const std::string& hex) {
  std::vector<uint8_t> out;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2)
    out.push_back(static_cast<uint8_t>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  return out;
}

int64_t now_us() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

template <class M>
std::vector<uint8_t> signed_bytes(const KeyRing& ring, std::size_t i, const char* channel, M m, int64_t timestamp_us,
                                  int64_t sender_id = -1) {
  m.sender_id = sender_id >= 0 ? sender_id : ring.sender_id(i);
  m.timestamp_us = timestamp_us;
  return ring.encode_signed(i, channel, m);
}

template <class M>
std::vector<uint8_t> encoded(const M& m) {
  std::vector<uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  return buf;
}

struct Verifier {
  explicit Verifier(AuthMode mode, std::shared_ptr<const KeyRing> ring) {
    std::string error;
    EXPECT_TRUE(auth.open(mode, std::move(ring), AuthConfig{}, &error)) << error;
  }
  // The verdict on a joystick_t's bytes: "" taken, else the refusal's text.
  std::string joystick(const std::vector<uint8_t>& b, CommandAuth::Stream stream = CommandAuth::kJoystickStream) {
    t1::joystick_t m{};
    EXPECT_EQ(m.decode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
    if (auth.verify(stream, t1::CH_JOYSTICK, b.data(), b.size(), m.sender_id, m.timestamp_us, m.tag_size)) return "";
    return refusal_text(auth.last_verdict());
  }
  CommandAuth auth;
};
}  // namespace

// The Python signer (messages/auth.py) and this code agree: same encoding up to the tag, same tags, same approval.
TEST(CommandAuth, AgreesWithThePythonGoldenVector) {
  std::ifstream in(std::string(T1_GOLDEN_DIR) + "/command_auth.json");
  ASSERT_TRUE(in) << "tests/golden/command_auth.json missing: python -m messages.auth golden tests/golden";
  const auto doc = nlohmann::json::parse(in);
  auto ring = test_ring("golden", {{7, doc["key_hex"].get<std::string>()}});
  ASSERT_TRUE(ring);
  t1::runtime_cmd_t cmd{};
  cmd.utime = 123456, cmd.seq = 5, cmd.verb = "load_policy", cmd.argument = "student/student.safetensors";
  t1::joystick_t stick{};
  stick.utime = 654321, stick.seq = 9, stick.vx = 0.5f, stick.vy = -0.25f, stick.yaw_rate = 0.125f;
  // The robot's state, signed the same way (messages/auth.py golden_document's fields).
  t1::imu_t imu{};
  imu.utime = 777000, imu.seq = 11, imu.quat[0] = 1.0f, imu.gyro[0] = 0.5f, imu.accel[2] = 9.81f;
  t1::joint_state_t joints{};
  joints.utime = 777000, joints.seq = 11;
  for (std::size_t i = 0; i < t1::kNumJoints; ++i)
    joints.q[i] = static_cast<float>(0.01 * static_cast<double>(i)),
    joints.motor_status[i] = static_cast<int32_t>(i % 3);
  int seen_state = 0;
  for (const auto& m : doc["messages"]) {
    const std::string channel = m["channel"];
    const int64_t ts = m["timestamp_us"];
    std::vector<uint8_t> mine;
    if (channel == t1::CH_RUNTIME_CMD) mine = signed_bytes(*ring, 0, t1::CH_RUNTIME_CMD, cmd, ts);
    else if (channel == t1::CH_JOYSTICK) mine = signed_bytes(*ring, 0, t1::CH_JOYSTICK, stick, ts);
    else if (channel == t1::CH_IMU) mine = signed_bytes(*ring, 0, t1::CH_IMU, imu, ts), ++seen_state;
    else mine = signed_bytes(*ring, 0, t1::CH_JOINT_STATE, joints, ts), ++seen_state;
    EXPECT_EQ(mine, from_hex(m["encoded_hex"])) << channel;
    EXPECT_EQ(m["tag_size"], static_cast<int>(kTagBytes)) << channel;
    EXPECT_EQ(std::vector<uint8_t>(mine.end() - kTagBytes, mine.end()), from_hex(m["tag_hex"])) << channel;
  }
  EXPECT_EQ(seen_state, 2) << "the golden vector holds a signed imu_t and joint_state_t";
  const auto& a = doc["approval"];
  const std::string approvals = own_path("golden", ".approvals");
  std::ofstream(approvals) << a["artifact_sha256_hex"].get<std::string>() << " 7 " << a["tag_hex"].get<std::string>()
                           << " golden\n";
  std::string why;
  EXPECT_TRUE(ring->approves(approvals, from_hex(a["artifact_sha256_hex"]).data(), &why)) << why;
}

TEST(CommandAuth, KeyFileOpenToOthersOrMalformedIsRefused) {
  std::string error;
  EXPECT_TRUE(KeyRing::load(write_key_file("ok", {test_sender(1, 1), test_sender(2, 2)}), &error)) << error;
  for (mode_t mode : {0640, 0604, 0660, 0644, 0610}) {
    EXPECT_FALSE(KeyRing::load(write_key_file("open", {test_sender(1, 1)}, mode), &error)) << std::oct << mode;
    EXPECT_NE(error.find("chmod 600"), std::string::npos) << error;
  }
  EXPECT_FALSE(KeyRing::load(own_path("missing", ".key"), &error));
  EXPECT_NE(error.find("No such file"), std::string::npos) << error;
  EXPECT_FALSE(KeyRing::load(write_key_file("dup", {test_sender(3, 1), test_sender(3, 2)}), &error));
  EXPECT_NE(error.find("listed twice"), std::string::npos) << error;
  for (auto bad :
       {std::pair<int64_t, std::string>{0, test_sender(1, 1).second}, {4, "abcd"}, {5, std::string(64, 'g')}}) {
    EXPECT_FALSE(KeyRing::load(write_key_file("bad", {bad}), &error)) << bad.first;
    EXPECT_NE(error.find("line 2"), std::string::npos) << error;
  }
  EXPECT_FALSE(KeyRing::load(write_key_file("empty", {}), &error));
  EXPECT_NE(error.find("no sender"), std::string::npos) << error;
}

TEST(CommandAuth, EveryRefusalReason) {
  auto ring = test_ring("reasons", {test_sender(1, 0x41), test_sender(2, 0x42)});
  auto stranger = test_ring("stranger", {test_sender(1, 0x99), test_sender(9, 0x43)});
  Verifier v(AuthMode::kSigned, ring);
  t1::joystick_t js{};
  js.vx = 0.3f;
  const int64_t t = now_us();
  const auto good = signed_bytes(*ring, 0, t1::CH_JOYSTICK, js, t);
  EXPECT_EQ(v.joystick(good), "");
  EXPECT_EQ(v.joystick(good), refusal_text(Refusal::kReplayed));  // same bytes again
  EXPECT_EQ(v.joystick(signed_bytes(*ring, 0, t1::CH_JOYSTICK, js, t - 1)), refusal_text(Refusal::kReplayed));
  // The same timestamp is new on the other channel's stream, and for the other sender.
  EXPECT_EQ(v.joystick(good, CommandAuth::kCommandStream), "");
  EXPECT_EQ(v.joystick(signed_bytes(*ring, 1, t1::CH_JOYSTICK, js, t)), "");
  const auto unsigned_js = encoded(js);  // default: sender 0, tag_size 0
  EXPECT_EQ(v.joystick(unsigned_js), refusal_text(Refusal::kUnsigned));
  t1::joystick_t untagged = js;  // a known sender's id, no tag
  untagged.sender_id = 1;
  untagged.timestamp_us = t + 5;
  EXPECT_EQ(v.joystick(encoded(untagged)), refusal_text(Refusal::kUnsigned));
  EXPECT_EQ(v.joystick(signed_bytes(*stranger, 1, t1::CH_JOYSTICK, js, t + 10)), refusal_text(Refusal::kUnknownSender));
  EXPECT_EQ(v.joystick(signed_bytes(*stranger, 0, t1::CH_JOYSTICK, js, t + 20)),
            refusal_text(Refusal::kBadTag));  // wrong key
  auto tampered = signed_bytes(*ring, 0, t1::CH_JOYSTICK, js, t + 30);
  tampered[8 + 8 + 8 + 3] ^= 0x40;  // vx's last byte
  EXPECT_EQ(v.joystick(tampered), refusal_text(Refusal::kBadTag));
  EXPECT_EQ(v.joystick(signed_bytes(*ring, 0, t1::CH_JOYSTICK, js, t + 40)), "");  // tampering moved nothing
  EXPECT_EQ(v.joystick(signed_bytes(*ring, 1, t1::CH_JOYSTICK, js, now_us() + 5'000'000)),
            refusal_text(Refusal::kStale));
  v.auth.refuse("joystick_t", 2);
  EXPECT_NE(std::string(v.auth.last_refusal()).find("stale timestamp (+"), std::string::npos) << v.auth.last_refusal();
  EXPECT_EQ(v.auth.refused(Refusal::kStale), 1);
  v.auth.refuse_tag_size("joystick_t", 5);
  EXPECT_NE(std::string(v.auth.last_refusal()).find("joystick_t: tag_size 5, neither 0"), std::string::npos)
      << v.auth.last_refusal();
  EXPECT_EQ(v.auth.refused(Refusal::kTagSize), 1);
  EXPECT_STREQ(v.auth.describe(), "signed (2 senders)");
  // A restarted runtime: the captured bytes are from before its start; an old timestamp is stale too.
  Verifier restarted(AuthMode::kSigned, ring);
  EXPECT_EQ(restarted.joystick(good), refusal_text(Refusal::kStale));
  EXPECT_EQ(restarted.joystick(signed_bytes(*ring, 1, t1::CH_JOYSTICK, js, now_us() - 5'000'000)),
            refusal_text(Refusal::kStale));
  EXPECT_EQ(restarted.joystick(signed_bytes(*ring, 1, t1::CH_JOYSTICK, js, now_us())), "");

  Verifier nobody(AuthMode::kEstopOnly, nullptr);
  EXPECT_EQ(nobody.joystick(good), refusal_text(Refusal::kNoKey));
  Verifier bench(AuthMode::kUnauthenticated, nullptr);
  EXPECT_EQ(bench.joystick(unsigned_js), "");
}

// The transport decodes a runtime_cmd_t / joystick_t only after reading its tag_size where lcm-gen's decoder
// will (which sizes the tag vector from it unchecked): every string length, every tag_size, and what no
// decoder may be given: a negative tag_size, a string length below 1, a datagram ending before tag_size.
TEST(CommandAuth, ReadsTagSizeWhereTheDecoderDoes) {
  auto ring = test_ring("tag_size", {test_sender(1, 0x61)});
  auto tag_size = [](CommandAuth::Stream stream, const std::vector<uint8_t>& b) {
    int n = -99;
    return CommandAuth::read_tag_size(stream, b.data(), b.size(), &n) ? n : -99;
  };
  for (const std::string& text : {std::string(), std::string("estop"), std::string(300, 'x')}) {
    t1::runtime_cmd_t c{};
    c.verb = text;
    c.argument = text + "/" + text;
    EXPECT_EQ(tag_size(CommandAuth::kCommandStream, encoded(c)), 0) << text.size();
    EXPECT_EQ(tag_size(CommandAuth::kCommandStream, signed_bytes(*ring, 0, t1::CH_RUNTIME_CMD, c, 1)), 32);
    c.tag_size = 5;
    c.tag.assign(5, 0xee);
    EXPECT_EQ(tag_size(CommandAuth::kCommandStream, encoded(c)), 5) << text.size();
  }
  t1::joystick_t js{};
  EXPECT_EQ(tag_size(CommandAuth::kJoystickStream, encoded(js)), 0);
  EXPECT_EQ(tag_size(CommandAuth::kJoystickStream, signed_bytes(*ring, 0, t1::CH_JOYSTICK, js, 1)), 32);
  auto negative = encoded(js);
  negative[negative.size() - 2] = negative[negative.size() - 1] = 0xff;
  EXPECT_EQ(tag_size(CommandAuth::kJoystickStream, negative), -1);
  EXPECT_FALSE(CommandAuth::tag_size_ok(-1));
  EXPECT_EQ(tag_size(CommandAuth::kJoystickStream, std::vector<uint8_t>(negative.begin(), negative.end() - 1)), -99);
  t1::runtime_cmd_t estop{};
  estop.verb = "estop";
  auto empty_verb = encoded(estop);
  const std::size_t verb_length_at = 3 * sizeof(int64_t);
  std::fill(empty_verb.begin() + verb_length_at, empty_verb.begin() + verb_length_at + 4, 0);  // length 0: no NUL
  EXPECT_EQ(tag_size(CommandAuth::kCommandStream, empty_verb), -99);
  EXPECT_EQ(tag_size(CommandAuth::kCommandStream, std::vector<uint8_t>(10, 0)), -99);
  std::vector<uint8_t> unsigned_estop = encoded(estop);
  EXPECT_FALSE(ring->sign(0, t1::CH_RUNTIME_CMD, unsigned_estop.data(), unsigned_estop.size())) << "no room for a tag";
}

// load_policy's name rules and the approvals.
class PolicyFolder : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = own_path("policy_folder", "");
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_ + "/sub");
    ArtifactSpec s = make_spec({8});
    s.meta["name"] = "approved";
    good_ = write_file(dir_ + "/sub/approved.safetensors", serialise(s));
    s.meta["name"] = "unapproved";
    write_file(dir_ + "/unapproved.safetensors", serialise(s));
    s.meta["name"] = "outside";
    outside_ = write_file(own_path("outside", ".safetensors"), serialise(s));
    std::filesystem::create_symlink(outside_, dir_ + "/link.safetensors");
    ring_ = test_ring("folder", {test_sender(4, 0x51)});
    approvals_ = dir_ + "/approvals";
    approve(*ring_, 0, approvals_, good_);
    approve(*ring_, 0, approvals_, outside_);  // approved content, but outside the folder
  }
  std::string refusal(const PolicyStore& store, const std::string& name) {
    try {
      store.load_name(name);
    } catch (const PolicyRefused& e) {
      return e.what();
    }
    return "";
  }
  std::string dir_, good_, outside_, approvals_;
  std::shared_ptr<const KeyRing> ring_;
};

TEST_F(PolicyFolder, NamesInsideOnlyAndApprovedContentOnly) {
  const PolicyStore store(dir_, ring_, approvals_);
  EXPECT_EQ(store.load_name("sub/approved.safetensors").name, "approved");
  const std::string up = "../" + outside_.substr(outside_.rfind('/') + 1);  // the outside file, by '..'
  EXPECT_NE(refusal(store, up).find("'..' leaves the policy folder"), std::string::npos);
  EXPECT_NE(refusal(store, "sub/../" + up).find("'..'"), std::string::npos);
  EXPECT_NE(refusal(store, outside_).find("an absolute path"), std::string::npos);
  EXPECT_NE(refusal(store, "link.safetensors").find("outside the policy folder"), std::string::npos);
  EXPECT_NE(refusal(store, "missing.safetensors").find("No such file"), std::string::npos);
  EXPECT_NE(refusal(store, "unapproved.safetensors").find("is not approved"), std::string::npos);
  EXPECT_NE(refusal(store, "").find("needs an artifact name"), std::string::npos);
  // An approval line made with another key (or edited) does not approve.
  auto forger = test_ring("forger", {test_sender(4, 0x52)});
  approve(*forger, 0, approvals_, dir_ + "/unapproved.safetensors");
  EXPECT_NE(refusal(store, "unapproved.safetensors").find("does not verify"), std::string::npos);
  // The startup path: inside the folder, approved.
  EXPECT_EQ(store.load_path(good_).name, "approved");
  EXPECT_THROW(store.load_path(outside_), PolicyRefused);
  // Without a key (--unauthenticated) the folder rule holds, content is not checked.
  const PolicyStore bench(dir_, nullptr, approvals_);
  EXPECT_EQ(bench.load_name("unapproved.safetensors").name, "unapproved");
  EXPECT_NE(refusal(bench, up).find("'..'"), std::string::npos);
}

// t1-runtime's start: a key file open to others, both modes at once, a startup policy outside the folder or not
// approved: refused with the exit code and a message naming the problem (never reaching LCM).
TEST_F(PolicyFolder, RuntimeRefusesToStartWithoutTheKeyRules) {
  auto run = [&](const std::string& args, std::string* err_text) {
    const std::string err = own_path("cli_auth", ".err");
    const int status =
        std::system((std::string(T1_RUNTIME_BIN) + " " + args + " --duration 0.1 --quiet 2> " + err).c_str());
    std::ifstream in(err);
    std::ostringstream ss;
    ss << in.rdbuf();
    *err_text = ss.str();
    return WEXITSTATUS(status);
  };
  std::string err;
  const std::string key = ring_->path(), open_key = write_key_file("cli_open", {test_sender(4, 0x51)}, 0644);
  const std::string folder = " --policy-dir " + dir_ + " --approvals " + approvals_;
  EXPECT_EQ(run("--policy " + good_ + " --key " + open_key + folder, &err), 6);
  EXPECT_NE(err.find("chmod 600"), std::string::npos) << err;
  EXPECT_EQ(run("--policy " + good_ + " --key " + key + " --unauthenticated", &err), 2);
  EXPECT_NE(err.find("exclude each other"), std::string::npos) << err;
  EXPECT_EQ(run("--policy " + outside_ + " --key " + key + folder, &err), 3);
  EXPECT_NE(err.find("outside the policy folder"), std::string::npos) << err;
  EXPECT_EQ(run("--policy " + dir_ + "/unapproved.safetensors --key " + key + folder, &err), 3);
  EXPECT_NE(err.find("is not approved"), std::string::npos) << err;
}
