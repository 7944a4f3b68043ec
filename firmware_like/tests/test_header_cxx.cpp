// The protocol header must compile as C++17 with C linkage (the runtime includes it); this also
// checks that the exact names other components code against exist with the expected types.
#include <cstdio>
#include <cstring>
#include <type_traits>

#include "t1_firmware.h"
#include "t1_motor_protocol.h"

static_assert(T1_NUM_MOTORS == 23, "23 motors");
static_assert(std::is_same<decltype(T1_MOTORS[0].motor_class), t1_motor_class_t>::value, "class field");
static_assert(std::is_same<decltype(T1_MOTORS[0].bus), uint8_t>::value, "bus field");
static_assert(T1_KP_MAX == 500.0f && T1_KD_MAX == 20.0f, "gain ranges");
static_assert((T1_STATUS_WATCHDOG & T1_STATUS_OVER_LIMIT & T1_STATUS_BAD_FRAME) == 0, "distinct bits");

int main() {
  int failures = 0;
  if (std::strcmp(T1_MOTORS[14].name, "Left_Knee_Pitch") != 0) ++failures;
  if (T1_MOTORS[14].torque_limit_nm != 60.0f) ++failures;
  if (T1_MOTORS[11].motor_class != T1_CLASS_HIP) ++failures;
  t1_motor_t m;
  if (t1_motor_init(&m, 0) != T1_OK) ++failures;
  std::printf("test_header_cxx: %d failures\n", failures);
  return failures == 0 ? 0 : 1;
}
