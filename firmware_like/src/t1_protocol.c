/* Data tables of the protocol (t1_motor_protocol.h): the per-motor table, class ranges, bus names and
 * the constants record read by bindings. The numbers themselves are written only in the header. */
#include "t1_firmware.h"

#define T1_MOTOR_ENTRY(index, name, cls, torque, qmin, qmax, dsafe, bus) \
  {name, cls, torque, qmin, qmax, dsafe, (uint8_t)(bus)},

const t1_motor_info_t T1_MOTORS[T1_NUM_MOTORS] = {T1_MOTOR_TABLE(T1_MOTOR_ENTRY)};

#undef T1_MOTOR_ENTRY

const t1_class_range_t T1_CLASS_RANGES[T1_NUM_CLASSES] = {
    /* T1_CLASS_HEAD  */ {T1_HEAD_V_MAX_RADS, T1_HEAD_T_MAX_NM},
    /* T1_CLASS_ARM   */ {T1_ARM_V_MAX_RADS, T1_ARM_T_MAX_NM},
    /* T1_CLASS_WAIST */ {T1_WAIST_V_MAX_RADS, T1_WAIST_T_MAX_NM},
    /* T1_CLASS_HIP   */ {T1_HIP_V_MAX_RADS, T1_HIP_T_MAX_NM},
    /* T1_CLASS_KNEE  */ {T1_KNEE_V_MAX_RADS, T1_KNEE_T_MAX_NM},
    /* T1_CLASS_ANKLE */ {T1_ANKLE_V_MAX_RADS, T1_ANKLE_T_MAX_NM},
};

const char* const T1_BUS_NAMES[T1_NUM_BUSES] = {"left_leg", "right_leg", "arms", "head_waist"};

const t1_protocol_constants_t T1_PROTOCOL = {
    T1_NUM_MOTORS,        T1_NUM_BUSES,         T1_CMD_ID_BASE,      T1_REPLY_ID_BASE,   T1_CMD_DLC,
    T1_REPLY_DLC,         T1_FRAME_SLOT_BYTES,  T1_BUS_BITRATE_BPS,  T1_BUS_CYCLE_US,    T1_WATCHDOG_US,
    T1_STATUS_WATCHDOG,   T1_STATUS_OVER_LIMIT, T1_STATUS_BAD_FRAME, T1_STATUS_POWER_ON, T1_STATUS_DAMPING,
    T1_STATUS_BAD_SENSOR, T1_Q_MAX_RAD,         T1_KP_MAX,           T1_KD_MAX,          T1_SOFT_STOP_FULL_TORQUE_RAD,
    T1_STATUS_NO_REPLY,
};

const char* t1_error_name(int code) {
  switch (code) {
    case T1_OK:
      return "ok";
    case T1_ERR_NONFINITE:
      return "non-finite float input";
    case T1_ERR_BAD_INDEX:
      return "motor/bus index out of range";
    case T1_ERR_BAD_DLC:
      return "frame length (DLC) differs from the protocol";
    case T1_ERR_BAD_ID:
      return "CAN id or motor id byte not the expected one";
    case T1_ERR_NULL:
      return "NULL pointer argument";
    default:
      return "unknown error code";
  }
}
