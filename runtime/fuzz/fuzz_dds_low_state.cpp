// libFuzzer harness: an rt/low_state sample as it comes off the wire, into the runtime's state.
// Input: the serialised sample (4-byte encapsulation header + CDR body), what a DataWriter sends.
// Path: Cyclone's own receive path for it (dds_stream_normalize_data: the check a reader makes of every
// received sample; dds_stream_read: the deserialisation dds_take does) -> DdsTransport::accept (check_low_state,
// rule R3, numbering, rule R12's sequence, low_state_to_messages) -> the slots -> a supervisor tick and a policy
// step on them. Each input is fed twice (the second one's lost-counter comparison runs).
#include <dds/ddsi/ddsi_cdrstream.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "fuzz_support.hpp"
#include "t1rt/dds_transport.hpp"
#include "t1rt/periodic_task.hpp"
#include "t1rt/transport.hpp"

namespace {
constexpr std::size_t kEncapsulationBytes = 4;
constexpr bool kLittleEndianHost = __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__;

// Encapsulation identifier (RTPS 10.5) -> XCDR version and whether the body is big-endian; false: unknown.
bool encoding_of(uint16_t id, uint32_t* xcdr_version, bool* big_endian) {
  switch (id) {
    case 0x0000:
    case 0x0001:
      *xcdr_version = 1;
      break;  // CDR_BE, CDR_LE
    case 0x0006:
    case 0x0007:
    case 0x0008:
    case 0x0009:
      *xcdr_version = 2;
      break;  // CDR2, D_CDR2
    default:
      return false;
  }
  *big_endian = (id & 1) == 0;
  return true;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace t1rt;
  if (size < kEncapsulationBytes || size > (1u << 20)) return 0;
  uint32_t xcdr = 0;
  bool big_endian = false;
  if (!encoding_of(static_cast<uint16_t>((data[0] << 8) | data[1]), &xcdr, &big_endian)) return 0;
  // Cyclone normalises in place, in a buffer of its own (aligned like its receive buffers).
  std::vector<uint64_t> aligned((size - kEncapsulationBytes + 7) / 8 + 1);
  char* body = reinterpret_cast<char*>(aligned.data());
  std::memcpy(body, data + kEncapsulationBytes, size - kEncapsulationBytes);
  const uint32_t body_size = static_cast<uint32_t>(size - kEncapsulationBytes);
  const uint32_t* ops = booster_interface_msg_dds__LowState__desc.m_ops;
  uint32_t offset = 0;
  if (!dds_stream_normalize_data(body, &offset, body_size, big_endian == kLittleEndianHost, xcdr, ops)) return 0;

  DdsLowState sample;
  std::memset(&sample, 0, sizeof(sample));
  dds_istream_t is;
  dds_istream_init(&is, offset, body, xcdr);
  dds_stream_read(&is, reinterpret_cast<char*>(&sample), ops);
  dds_istream_fini(&is);

  Supervisor supervisor;
  supervisor.set_autostart(true);
  LcmTransport slots;  // the live state slots the Controller hands the DDS link (no socket opened)
  bool new_state = false;
  DdsTransport link;
  link.attach(ClockMode::kRealtime, &supervisor, &slots.imu, &slots.joint, &new_state);
  link.accept(sample);
  link.accept(sample);
  dds_stream_free_sample(&sample, ops);

  static PolicyEngine engine(fuzz::small_artifact());
  engine.reset();
  const float command[3] = {0, 0, 0};
  fuzz::loop_tick(supervisor, engine, slots.state_view(monotonic_s(), false), command);
  return 0;
}
