#include "t1rt/dds_transport.hpp"

#include <cmath>
#include <cstdio>
#include <utility>

#include "t1_contract.hpp"
#include "t1_motor_protocol.h"
#include "t1rt/periodic_task.hpp"
#include "t1rt/policy.hpp"
#include "t1rt/safety.hpp"

namespace t1rt {

namespace {
constexpr double kSToUs = 1e6;
constexpr int64_t kMsToNs = 1'000'000;
static_assert(t1::kNumJoints == kJoints, "contract joint count differs from the runtime's");

bool finite3(const float* v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

std::string dds_error(const char* what, dds_return_t rc) {
  return std::string(what) + " failed: " + dds_strretcode(rc) +
         " (Cyclone config: $CYCLONEDDS_URI; run inside tools/netns, which sets a loopback-only one)";
}
}  // namespace

const char* check_low_state(const DdsLowState& s) {
  if (s.motor_state_serial._length != kJoints)
    return s.motor_state_serial._length > kJoints ? "LowState_ rejected: more than 23 serial motor states"
                                                  : "LowState_ rejected: fewer than 23 serial motor states";
  const auto& imu = s.imu_state;
  if (!finite3(imu.rpy) || !finite3(imu.gyro) || !finite3(imu.acc)) return "LowState_ rejected: non-finite IMU value";
  for (uint32_t i = 0; i < kJoints; ++i) {
    const auto& m = s.motor_state_serial._buffer[i];
    if (!std::isfinite(m.q) || !std::isfinite(m.dq) || !std::isfinite(m.tau_est))
      return "LowState_ rejected: non-finite motor q, dq or tau_est";
  }
  return nullptr;
}

void low_state_to_messages(const DdsLowState& s, t1::imu_t* imu, t1::joint_state_t* joint, const uint32_t* prev_lost) {
  quat_from_rpy(s.imu_state.rpy, imu->quat);
  for (int k = 0; k < 3; ++k) {
    imu->gyro[k] = s.imu_state.gyro[k];
    imu->accel[k] = s.imu_state.acc[k];
  }
  for (std::size_t i = 0; i < kJoints; ++i) {
    const auto& m = s.motor_state_serial._buffer[i];
    joint->q[i] = m.q;
    joint->dq[i] = m.dq;
    joint->tau_est[i] = m.tau_est;
    // lost counts the motor's missed replies: a change since the last sample means none came (rule R8).
    joint->motor_status[i] = prev_lost && m.lost != prev_lost[i] ? static_cast<int32_t>(T1_STATUS_NO_REPLY) : 0;
  }
}

void joint_command_to_low_cmd(const t1::joint_command_t& cmd, DdsLowCmd* out, DdsMotorCmd* motors) {
  out->cmd_type = static_cast<booster_interface_msg_dds__CmdType_>(t1::kDdsCmdTypeSerial);
  out->motor_cmd._buffer = motors;
  out->motor_cmd._length = out->motor_cmd._maximum = static_cast<uint32_t>(kJoints);
  out->motor_cmd._release = false;  // the runtime owns the buffer: Cyclone must never free it
  for (std::size_t i = 0; i < kJoints; ++i) {
    DdsMotorCmd& m = motors[i];
    m.mode = static_cast<uint8_t>(t1::kDdsMotorMode);
    m.q = cmd.q_des[i];
    m.dq = cmd.dq_des[i];
    m.tau = cmd.tau_ff[i];
    m.kp = cmd.kp[i];
    m.kd = cmd.kd[i];
    m.weight = t1::kDdsMotorWeight;
  }
}

DdsTransport::~DdsTransport() {
  if (participant_ > 0) dds_delete(participant_);  // deletes the readers, writers, topics and waitset too
}

bool DdsTransport::open(int domain_id, ClockMode clock, Supervisor* supervisor, MessageSlot<t1::imu_t>* imu,
                        MessageSlot<t1::joint_state_t>* joint, bool* new_state, std::string* error,
                        double restart_quiet_s) {
  restart_quiet_s_ = restart_quiet_s;
  attach(clock, supervisor, imu, joint, new_state);
  participant_ = dds_create_participant(static_cast<dds_domainid_t>(domain_id), nullptr, nullptr);
  if (participant_ < 0) {
    *error = dds_error("dds_create_participant", participant_);
    return false;
  }
  const dds_entity_t state_topic =
      dds_create_topic(participant_, &booster_interface_msg_dds__LowState__desc, t1::kDdsStateTopic, nullptr, nullptr);
  const dds_entity_t cmd_topic =
      dds_create_topic(participant_, &booster_interface_msg_dds__LowCmd__desc, t1::kDdsCommandTopic, nullptr, nullptr);
  if (state_topic < 0 || cmd_topic < 0) {
    *error = dds_error("dds_create_topic", state_topic < 0 ? state_topic : cmd_topic);
    return false;
  }
  // State: best effort (a best-effort reader matches a reliable or a best-effort robot), the last
  // kTakeBatch samples: LowState_ has no key, so with a depth of 1 a second writer's sample would overwrite
  // the robot's before the loop takes it (the robot's state starved); taken in order, the newest last.
  // Command: reliable, newest only, as the robot's ROS 2 variant declares joint_ctrl.
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, kTakeBatch);
  state_reader_ = dds_create_reader(participant_, state_topic, qos, nullptr);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  cmd_writer_ = dds_create_writer(participant_, cmd_topic, qos, nullptr);
  dds_delete_qos(qos);
  if (state_reader_ < 0 || cmd_writer_ < 0) {
    *error = dds_error(state_reader_ < 0 ? "dds_create_reader" : "dds_create_writer",
                       state_reader_ < 0 ? state_reader_ : cmd_writer_);
    return false;
  }
  dds_set_status_mask(state_reader_, DDS_DATA_AVAILABLE_STATUS | DDS_SAMPLE_LOST_STATUS);
  waitset_ = dds_create_waitset(participant_);
  dds_waitset_attach(waitset_, state_reader_, state_reader_);
  return true;
}

void DdsTransport::attach(ClockMode clock, Supervisor* supervisor, MessageSlot<t1::imu_t>* imu,
                          MessageSlot<t1::joint_state_t>* joint, bool* new_state) {
  clock_ = clock;
  supervisor_ = supervisor;
  imu_ = imu;
  joint_ = joint;
  new_state_ = new_state;
}

void DdsTransport::accept(const DdsLowState& sample) {
  if (const char* why = check_low_state(sample)) {
    ++rejected;
    std::snprintf(last_reject.data(), last_reject.size(), "%s", why);
    return;
  }
  const int64_t seq = accepted_ + lost;  // arrival order; samples DDS lost show up as gaps
  const double now_s = monotonic_s();
  if (supervisor_ && !(supervisor_->accept_imu_seq(seq, now_s) && supervisor_->accept_joint_seq(seq, now_s))) return;
  low_state_to_messages(sample, &imu_->scratch, &joint_->scratch, accepted_ > 0 ? lost_seen_.data() : nullptr);
  for (std::size_t i = 0; i < kJoints; ++i) lost_seen_[i] = sample.motor_state_serial._buffer[i].lost;
  // Lockstep: one state per control period, so the state's own time is its number times the loop dt.
  const double stamp_s = clock_ == ClockMode::kLockstep ? static_cast<double>(accepted_) * kLoopDtS : monotonic_s();
  imu_->scratch.seq = joint_->scratch.seq = seq;
  imu_->scratch.utime = joint_->scratch.utime = static_cast<int64_t>(stamp_s * kSToUs);
  std::swap(imu_->msg, imu_->scratch);
  std::swap(joint_->msg, joint_->scratch);
  for (auto* stamp : {&imu_->stamp_s, &joint_->stamp_s}) *stamp = stamp_s;
  imu_->have = joint_->have = true;
  ++imu_->received;
  ++joint_->received;
  ++accepted_;
  *new_state_ = true;
}

void DdsTransport::format_guid(dds_instance_handle_t writer, std::array<char, 48>* out) const {
  // The matched writer's built-in topic data holds its GUID (allocated by Cyclone: only when a writer is
  // first followed or first refused, not per sample).
  dds_builtintopic_endpoint_t* ep = dds_get_matched_publication_data(state_reader_, writer);
  if (!ep) {
    std::snprintf(out->data(), out->size(), "handle %016llx", static_cast<unsigned long long>(writer));
    return;
  }
  char* p = out->data();
  for (std::size_t i = 0; i < sizeof(ep->key.v); ++i) p += std::snprintf(p, 3, "%02x", ep->key.v[i]);
  dds_builtintopic_free_endpoint(ep);
}

bool DdsTransport::from_followed_writer(dds_instance_handle_t writer, double now_s) {
  if (writer == writer_) {
    writer_last_s_ = now_s;
    return true;
  }
  if (writer_ == 0 || now_s - writer_last_s_ >= restart_quiet_s_) {  // the first writer, or the old one is silent
    if (writer_ != 0) ++writer_changes;
    writer_ = writer;
    writer_last_s_ = now_s;
    format_guid(writer, &followed);
    return true;
  }
  ++other_writer_samples;
  if (writer != named_other_) {
    named_other_ = writer;
    std::array<char, 48> guid{};
    format_guid(writer, &guid);
    std::snprintf(other_writer.data(), other_writer.size(), "refused rt/low_state of a second writer %s (following %s)",
                  guid.data(), followed.data());
  }
  return false;
}

int DdsTransport::take() {
  dds_sample_lost_status_t lost_status;
  if (dds_get_sample_lost_status(state_reader_, &lost_status) == DDS_RETCODE_OK) lost += lost_status.total_count_change;
  void* samples[kTakeBatch] = {nullptr};
  dds_sample_info_t infos[kTakeBatch];
  int taken_valid = 0;
  for (;;) {
    // Loaned samples: Cyclone deserialises into its own buffers, returned below.
    const dds_return_t n = dds_take(state_reader_, samples, infos, kTakeBatch, kTakeBatch);
    if (n <= 0) break;
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;  // dispose / unregister notifications carry no state
      if (!from_followed_writer(infos[i].publication_handle, monotonic_s())) continue;
      accept(*static_cast<const DdsLowState*>(samples[i]));
      ++taken_valid;
    }
    dds_return_loan(state_reader_, samples, n);
    if (n < kTakeBatch) break;
  }
  return taken_valid;
}

int DdsTransport::wait(int timeout_ms) {
  if (int n = take(); n > 0) return n;
  const dds_return_t rc = dds_waitset_wait(waitset_, nullptr, 0, static_cast<dds_duration_t>(timeout_ms) * kMsToNs);
  if (rc < 0) return rc;
  return take();
}

void DdsTransport::drain() { take(); }

bool DdsTransport::publish(const t1::joint_command_t& cmd) {
  joint_command_to_low_cmd(cmd, &low_cmd_, motors_.data());
  return dds_write(cmd_writer_, &low_cmd_) == DDS_RETCODE_OK;
}

}  // namespace t1rt
