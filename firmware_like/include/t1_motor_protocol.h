/*
 * t1_motor_protocol.h — the Booster T1 motor bus protocol, in one place.
 *
 * A reader should learn the whole protocol from this file (in the spirit of MIT Cheetah's
 * SimulatorMessage.h): who sits on which bus, which CAN ids they use, how a command and a reply are
 * packed into bytes, the scaling range of every field, the per-motor limits, and what each status bit
 * means. The implementation (codec, motor step, bus model) lives in firmware_like/src and is declared
 * in t1_firmware.h. C99 and C++17 both compile this header.
 *
 * ---------------------------------------------------------------------------------------------------
 * 1. Motors and ids
 *   23 motors, one per actuated joint. motor_id = joint index + 1 (1..23), joint order of
 *   messages/contract.json (= MuJoCo actuator order, t1_facts.md §2a). motor_id 0 is never used, so an
 *   all-zero reply frame can never be mistaken for a motor's answer.
 *
 *   CAN 2.0A standard (11-bit) identifiers:
 *     command frame (host → motor)  id = 0x100 + motor_id   (0x101 … 0x117)
 *     reply frame   (motor → host)  id = 0x200 + motor_id   (0x201 … 0x217)
 *   In CAN arbitration the LOWER id wins. Every command id is below every reply id, so when the host
 *   and a motor start transmitting together the command goes first: a late command costs control
 *   quality, a late reply only costs one sample of state age.
 *
 * 2. Buses (4 × 1 Mbit/s; one bus cycle = one control period = 2 ms = 2000 bit times)
 *     bus 0  left leg    6 motors  (Left_Hip_Pitch … Left_Ankle_Roll,   joints 11–16)
 *     bus 1  right leg   6 motors  (Right_Hip_Pitch … Right_Ankle_Roll, joints 17–22)
 *     bus 2  arms        8 motors  (both shoulders and elbows,          joints 2–9)
 *     bus 3  head+waist  3 motors  (AAHead_yaw, Head_pitch, Waist,      joints 0, 1, 10)
 *   Per cycle each motor receives one command and sends one reply. A frame whose last bit would end
 *   after the cycle's 2000 bit times is LATE (the bus model reports it; the simulator does not deliver
 *   it in that cycle).
 *
 * 3. Command frame, DLC 8 (MIT mini-cheetah packing, big-endian bit stream, MSB first)
 *     byte 0     1     2     3          4     5     6          7
 *          [ q_des 16  ][ dq_des 12  ][ kp 12       ][ kd 12     ][ tau_ff 12 ]
 *     b0 = q>>8        b1 = q & 0xFF
 *     b2 = dq>>4       b3 = (dq & 0xF)<<4 | kp>>8    b4 = kp & 0xFF
 *     b5 = kd>>4       b6 = (kd & 0xF)<<4 | tau>>8   b7 = tau & 0xFF
 *
 * 4. Reply frame, DLC 7
 *     byte 0          1     2      3           4            5       6
 *          [motor_id 8][ q 16      ][ dq 12     ][ tau 12      ][status 8]
 *     b0 = motor_id    b1 = q>>8    b2 = q & 0xFF
 *     b3 = dq>>4       b4 = (dq & 0xF)<<4 | tau>>8   b5 = tau & 0xFF    b6 = status bits (§7)
 *   The reply torque is the torque the motor applied in its last step (after every clamp).
 *
 * 5. Fixed-point scaling: code = round((x − lo) · (2^bits − 1) / (hi − lo)), x clamped to [lo, hi]
 *   first (a value beyond the range encodes as the edge); decode x = lo + code · (hi − lo)/(2^bits − 1).
 *   Round trip error ≤ half a step. Non-finite values are bad input: the encoder refuses them
 *   (T1_ERR_NONFINITE) and never puts a frame on the bus. Symmetric ranges have no exact zero code
 *   (2^bits − 1 is odd): a commanded 0 comes back as ±half a step (e.g. ±0.011 N·m on a hip).
 *     field     bits  range
 *     q         16    ±T1_Q_MAX_RAD = ±4.0 rad for every class (covers every joint range of
 *                     t1_facts §2a; the widest is shoulder pitch −3.31 … 1.22)
 *     dq        12    ±v_max of the class = 2 × the class's largest URDF velocity limit (falls and
 *                     impacts drive joints faster than the rated speed; the reply must not clip there)
 *     kp        12    0 … T1_KP_MAX = 500 N·m/rad (all classes: one gain set is shared by all policies)
 *     kd        12    0 … T1_KD_MAX = 20 N·m·s/rad (all classes)
 *     tau       12    ±t_max of the class = the class's largest torque limit
 *
 *     class  members                       v_max [rad/s]          t_max [N·m]
 *     HEAD   head yaw, head pitch          25.12 (2 × 12.56)      7
 *     ARM    shoulders, elbows             37.68 (2 × 18.84)      18
 *     WAIST  waist yaw                     21.76 (2 × 10.88)      30
 *     HIP    hip pitch, roll, yaw          25.00 (2 × 12.5)       45 (pitch; roll/yaw are 30)
 *     KNEE   knees                         23.40 (2 × 11.7)       60
 *     ANKLE  ankle pitch, roll             37.60 (2 × 18.8)       20 (pitch; roll is 15)
 *
 * 6. Motor behaviour (firmware step, called at the physics rate, 500 Hz here)
 *   normal   τ = kp·(q_des − q) + kd·(dq_des − dq) + τ_ff, with the last valid command.
 *   damping  τ = −d_safe·dq (kp = 0). Active at power-on (no valid command ever received) and after
 *            a watchdog timeout: more than T1_WATCHDOG_US = 50 ms since the last valid command
 *            (exactly 50 ms is still on time). A fresh valid command leaves damping at once.
 *            Power-on is damping, not zero torque, so a robot switched on mid-fall is slowed down.
 *   soft stop   beyond a joint-range end (q_min/q_max below), a restoring spring-damper is added in
 *            every mode: τ_stop = k_stop·(q_stop − q) − d_safe·dq_outward with
 *            k_stop = torque_limit / T1_SOFT_STOP_FULL_TORQUE_RAD (full torque 0.1 rad past the stop)
 *            and the damper acting only on the velocity that moves further out (it never fights the
 *            return).
 *   clamp    the total is clamped to ±torque_limit of the motor (per joint, not per class).
 *   sensor   a non-finite q or dq gives τ = 0 and T1_STATUS_BAD_SENSOR for that step.
 *
 *   d_safe (watchdog damping) = torque_limit / URDF velocity limit, rounded to 0.01: the damping
 *   torque reaches the motor's limit exactly at its rated speed, so damping is as strong as it can be
 *   without saturating inside the rated range (saturation would make the damping stop being damping).
 *
 * 7. Status bits (reply byte 6; joint_state_t.motor_status carries them unchanged)
 *     bit  name          meaning                                                    lifetime
 *     0x01 WATCHDOG      > 50 ms without a valid command → damping                 clears on the next valid command
 *     0x02 OVER_LIMIT    last step saturated the torque or q was beyond a soft stop recomputed every step
 *     0x04 BAD_FRAME     a frame was rejected (wrong DLC, wrong id) since the       LATCHED until the next valid
 *                        last valid command; the previous command stays in force    command
 *     0x08 POWER_ON      no valid command received since reset → damping           clears on the first valid command
 *     0x10 DAMPING       damping mode is active (POWER_ON or WATCHDOG)             follows the mode
 *     0x20 BAD_SENSOR    last step had a non-finite q or dq → τ = 0                recomputed every step
 *   T1_STATUS_NOT_FOLLOWING = WATCHDOG | POWER_ON | DAMPING: the motor ignores the command. OVER_LIMIT
 *   is expected during falls and getups; a controller should treat it as information, not a fault.
 *   Host bit (above the reply byte, so no motor can send it; the host's bus driver sets it in
 *   joint_state_t.motor_status, sim_hil/motor_bus.py):
 *     0x100 NO_REPLY     no reply frame from this motor in this bus cycle (the motor is silent, or its   this cycle only
 *                        frame was lost or late); q, dq, tau and the other bits are the last received
 *   A single NO_REPLY is normal on a real bus (lost frames); the runtime faults only on a run of them
 *   (runtime/src/safety_supervisor.cpp, rule R8). On the DDS link the robot sends no status byte: the
 *   runtime derives NO_REPLY from MotorState_.lost (messages/dds/booster_low.idl says how).
 * ---------------------------------------------------------------------------------------------------
 */
#ifndef T1_MOTOR_PROTOCOL_H
#define T1_MOTOR_PROTOCOL_H

#include <stdint.h>

#include "t1_joint_ranges.h" /* generated from messages/contract.json */

#ifdef __cplusplus
extern "C" {
#endif

/* ---- ids ---- */
#define T1_NUM_MOTORS 23
#define T1_NUM_BUSES 4
#define T1_NUM_CLASSES 6
#define T1_CMD_ID_BASE 0x100u    /* command id = base + motor_id */
#define T1_REPLY_ID_BASE 0x200u  /* reply id = base + motor_id (lower priority than any command) */
#define T1_CAN_STD_ID_MAX 0x7FFu /* 11-bit identifier */
#define T1_MOTOR_ID_OF_INDEX(i) ((uint8_t)((i) + 1))
#define T1_CMD_CAN_ID(i) (T1_CMD_ID_BASE + (uint32_t)T1_MOTOR_ID_OF_INDEX(i))
#define T1_REPLY_CAN_ID(i) (T1_REPLY_ID_BASE + (uint32_t)T1_MOTOR_ID_OF_INDEX(i))

/* ---- frames ---- */
#define T1_CMD_DLC 8
#define T1_REPLY_DLC 7
#define T1_FRAME_SLOT_BYTES 8 /* batch buffers hold one 8-byte slot per motor; replies pad byte 7 = 0 */

/* ---- field widths ---- */
#define T1_Q_BITS 16
#define T1_DQ_BITS 12
#define T1_KP_BITS 12
#define T1_KD_BITS 12
#define T1_TAU_BITS 12

/* ---- field ranges ---- */
#define T1_Q_MAX_RAD 4.0f /* ±, all classes */
#define T1_KP_MAX 500.0f  /* N·m/rad, command-frame kp range upper edge (lower edge 0) */
#define T1_KD_MAX 20.0f   /* N·m·s/rad (lower edge 0) */

/* velocity range ±(2 × the class's largest URDF velocity limit) [rad/s] */
#define T1_HEAD_V_MAX_RADS 25.12f
#define T1_ARM_V_MAX_RADS 37.68f
#define T1_WAIST_V_MAX_RADS 21.76f
#define T1_HIP_V_MAX_RADS 25.0f
#define T1_KNEE_V_MAX_RADS 23.4f
#define T1_ANKLE_V_MAX_RADS 37.6f
/* torque range ± the class's largest torque limit [N·m] */
#define T1_HEAD_T_MAX_NM 7.0f
#define T1_ARM_T_MAX_NM 18.0f
#define T1_WAIST_T_MAX_NM 30.0f
#define T1_HIP_T_MAX_NM 45.0f
#define T1_KNEE_T_MAX_NM 60.0f
#define T1_ANKLE_T_MAX_NM 20.0f

/* ---- timing ---- */
#define T1_BUS_BITRATE_BPS 1000000u /* 1 Mbit/s on every bus */
#define T1_BUS_CYCLE_US 2000u       /* bus cycle = control period = physics step, 2 ms */
#define T1_WATCHDOG_US 50000u       /* > 50 ms without a valid command → damping */

/* ---- motor behaviour ---- */
#define T1_SOFT_STOP_FULL_TORQUE_RAD 0.1f /* soft-stop spring reaches the torque limit 0.1 rad past a stop */

/* ---- status bits (reply byte 6) ---- */
#define T1_STATUS_WATCHDOG 0x01u
#define T1_STATUS_OVER_LIMIT 0x02u
#define T1_STATUS_BAD_FRAME 0x04u
#define T1_STATUS_POWER_ON 0x08u
#define T1_STATUS_DAMPING 0x10u
#define T1_STATUS_BAD_SENSOR 0x20u
#define T1_STATUS_NOT_FOLLOWING (T1_STATUS_WATCHDOG | T1_STATUS_POWER_ON | T1_STATUS_DAMPING)
#define T1_STATUS_NO_REPLY 0x100u /* host bit, never on the wire: no reply frame this bus cycle (§7) */

typedef enum {
  T1_CLASS_HEAD,
  T1_CLASS_ARM,
  T1_CLASS_WAIST,
  T1_CLASS_HIP,
  T1_CLASS_KNEE,
  T1_CLASS_ANKLE
} t1_motor_class_t;

typedef enum { T1_BUS_LEFT_LEG = 0, T1_BUS_RIGHT_LEG = 1, T1_BUS_ARMS = 2, T1_BUS_HEAD_WAIST = 3 } t1_bus_id_t;

/* Scaling range of one motor class (the wire format's ranges; §5). */
typedef struct {
  float v_max_rads; /* dq field range ±v_max [rad/s] */
  float t_max_nm;   /* tau field range ±t_max [N·m] */
} t1_class_range_t;

typedef struct {
  const char* name;             /* joint name, messages/contract.json */
  t1_motor_class_t motor_class; /* selects the wire scaling ranges */
  float torque_limit_nm;        /* per-joint clamp [N·m] (t1_facts §2a actuatorfrcrange) */
  float q_min_rad;              /* soft stop = joint range lower end [rad] */
  float q_max_rad;              /* soft stop = joint range upper end [rad] */
  float d_safe_nms;             /* watchdog / power-on damping gain [N·m·s/rad] */
  uint8_t bus;                  /* t1_bus_id_t */
} t1_motor_info_t;

/*
 * The per-motor table, joint order, as an X-macro so this header is the only place it is written:
 *   X(index, name, class, torque_limit [N·m], q_min [rad], q_max [rad], d_safe [N·m·s/rad], bus)
 * q_min / q_max: the joint's range from messages/contract.json (joint_ranges_rad), through the build's generated
 * t1_joint_ranges.h: one source for these soft stops and the MuJoCo model's joint limits.
 * d_safe = torque limit / URDF velocity limit (§6): head 7/12.56, arm 18/18.84, waist 30/10.88,
 * hip pitch 45/12.5, hip roll & yaw 30/10.9, knee 60/11.7, ankle pitch 20/18.8, ankle roll 15/12.4.
 */
/* one motor per row, the columns aligned: */
/* clang-format off */
#define T1_MOTOR_TABLE(X)                                                                                \
  X(0, "AAHead_yaw", T1_CLASS_HEAD, 7.0f,                                                                \
    T1_Q_MIN_RAD_AAHead_yaw, T1_Q_MAX_RAD_AAHead_yaw, 0.56f, T1_BUS_HEAD_WAIST)                          \
  X(1, "Head_pitch", T1_CLASS_HEAD, 7.0f,                                                                \
    T1_Q_MIN_RAD_Head_pitch, T1_Q_MAX_RAD_Head_pitch, 0.56f, T1_BUS_HEAD_WAIST)                          \
  X(2, "Left_Shoulder_Pitch", T1_CLASS_ARM, 18.0f,                                                       \
    T1_Q_MIN_RAD_Left_Shoulder_Pitch, T1_Q_MAX_RAD_Left_Shoulder_Pitch, 0.96f, T1_BUS_ARMS)              \
  X(3, "Left_Shoulder_Roll", T1_CLASS_ARM, 18.0f,                                                        \
    T1_Q_MIN_RAD_Left_Shoulder_Roll, T1_Q_MAX_RAD_Left_Shoulder_Roll, 0.96f, T1_BUS_ARMS)                \
  X(4, "Left_Elbow_Pitch", T1_CLASS_ARM, 18.0f,                                                          \
    T1_Q_MIN_RAD_Left_Elbow_Pitch, T1_Q_MAX_RAD_Left_Elbow_Pitch, 0.96f, T1_BUS_ARMS)                    \
  X(5, "Left_Elbow_Yaw", T1_CLASS_ARM, 18.0f,                                                            \
    T1_Q_MIN_RAD_Left_Elbow_Yaw, T1_Q_MAX_RAD_Left_Elbow_Yaw, 0.96f, T1_BUS_ARMS)                        \
  X(6, "Right_Shoulder_Pitch", T1_CLASS_ARM, 18.0f,                                                      \
    T1_Q_MIN_RAD_Right_Shoulder_Pitch, T1_Q_MAX_RAD_Right_Shoulder_Pitch, 0.96f, T1_BUS_ARMS)            \
  X(7, "Right_Shoulder_Roll", T1_CLASS_ARM, 18.0f,                                                       \
    T1_Q_MIN_RAD_Right_Shoulder_Roll, T1_Q_MAX_RAD_Right_Shoulder_Roll, 0.96f, T1_BUS_ARMS)              \
  X(8, "Right_Elbow_Pitch", T1_CLASS_ARM, 18.0f,                                                         \
    T1_Q_MIN_RAD_Right_Elbow_Pitch, T1_Q_MAX_RAD_Right_Elbow_Pitch, 0.96f, T1_BUS_ARMS)                  \
  X(9, "Right_Elbow_Yaw", T1_CLASS_ARM, 18.0f,                                                           \
    T1_Q_MIN_RAD_Right_Elbow_Yaw, T1_Q_MAX_RAD_Right_Elbow_Yaw, 0.96f, T1_BUS_ARMS)                      \
  X(10, "Waist", T1_CLASS_WAIST, 30.0f,                                                                  \
    T1_Q_MIN_RAD_Waist, T1_Q_MAX_RAD_Waist, 2.76f, T1_BUS_HEAD_WAIST)                                    \
  X(11, "Left_Hip_Pitch", T1_CLASS_HIP, 45.0f,                                                           \
    T1_Q_MIN_RAD_Left_Hip_Pitch, T1_Q_MAX_RAD_Left_Hip_Pitch, 3.60f, T1_BUS_LEFT_LEG)                    \
  X(12, "Left_Hip_Roll", T1_CLASS_HIP, 30.0f,                                                            \
    T1_Q_MIN_RAD_Left_Hip_Roll, T1_Q_MAX_RAD_Left_Hip_Roll, 2.75f, T1_BUS_LEFT_LEG)                      \
  X(13, "Left_Hip_Yaw", T1_CLASS_HIP, 30.0f,                                                             \
    T1_Q_MIN_RAD_Left_Hip_Yaw, T1_Q_MAX_RAD_Left_Hip_Yaw, 2.75f, T1_BUS_LEFT_LEG)                        \
  X(14, "Left_Knee_Pitch", T1_CLASS_KNEE, 60.0f,                                                         \
    T1_Q_MIN_RAD_Left_Knee_Pitch, T1_Q_MAX_RAD_Left_Knee_Pitch, 5.13f, T1_BUS_LEFT_LEG)                  \
  X(15, "Left_Ankle_Pitch", T1_CLASS_ANKLE, 20.0f,                                                       \
    T1_Q_MIN_RAD_Left_Ankle_Pitch, T1_Q_MAX_RAD_Left_Ankle_Pitch, 1.06f, T1_BUS_LEFT_LEG)                \
  X(16, "Left_Ankle_Roll", T1_CLASS_ANKLE, 15.0f,                                                        \
    T1_Q_MIN_RAD_Left_Ankle_Roll, T1_Q_MAX_RAD_Left_Ankle_Roll, 1.21f, T1_BUS_LEFT_LEG)                  \
  X(17, "Right_Hip_Pitch", T1_CLASS_HIP, 45.0f,                                                          \
    T1_Q_MIN_RAD_Right_Hip_Pitch, T1_Q_MAX_RAD_Right_Hip_Pitch, 3.60f, T1_BUS_RIGHT_LEG)                 \
  X(18, "Right_Hip_Roll", T1_CLASS_HIP, 30.0f,                                                           \
    T1_Q_MIN_RAD_Right_Hip_Roll, T1_Q_MAX_RAD_Right_Hip_Roll, 2.75f, T1_BUS_RIGHT_LEG)                   \
  X(19, "Right_Hip_Yaw", T1_CLASS_HIP, 30.0f,                                                            \
    T1_Q_MIN_RAD_Right_Hip_Yaw, T1_Q_MAX_RAD_Right_Hip_Yaw, 2.75f, T1_BUS_RIGHT_LEG)                     \
  X(20, "Right_Knee_Pitch", T1_CLASS_KNEE, 60.0f,                                                        \
    T1_Q_MIN_RAD_Right_Knee_Pitch, T1_Q_MAX_RAD_Right_Knee_Pitch, 5.13f, T1_BUS_RIGHT_LEG)               \
  X(21, "Right_Ankle_Pitch", T1_CLASS_ANKLE, 20.0f,                                                      \
    T1_Q_MIN_RAD_Right_Ankle_Pitch, T1_Q_MAX_RAD_Right_Ankle_Pitch, 1.06f, T1_BUS_RIGHT_LEG)             \
  X(22, "Right_Ankle_Roll", T1_CLASS_ANKLE, 15.0f,                                                       \
    T1_Q_MIN_RAD_Right_Ankle_Roll, T1_Q_MAX_RAD_Right_Ankle_Roll, 1.21f, T1_BUS_RIGHT_LEG)
/* clang-format on */

extern const t1_motor_info_t T1_MOTORS[T1_NUM_MOTORS];         /* joint order */
extern const t1_class_range_t T1_CLASS_RANGES[T1_NUM_CLASSES]; /* indexed by t1_motor_class_t */
extern const char* const T1_BUS_NAMES[T1_NUM_BUSES];           /* "left_leg", "right_leg", "arms", "head_waist" */

/*
 * The same constants as data, so a binding (sim_hil/firmware.py) reads them from the library instead
 * of copying numbers out of this header.
 */
typedef struct {
  uint32_t num_motors, num_buses;
  uint32_t cmd_id_base, reply_id_base;
  uint32_t cmd_dlc, reply_dlc, slot_bytes;
  uint32_t bitrate_bps, cycle_us, watchdog_us;
  uint32_t status_watchdog, status_over_limit, status_bad_frame, status_power_on, status_damping, status_bad_sensor;
  float q_max_rad, kp_max, kd_max, soft_stop_full_torque_rad;
  uint32_t status_no_reply; /* host bit (§7); last, so the fields above keep their offsets */
} t1_protocol_constants_t;
extern const t1_protocol_constants_t T1_PROTOCOL;

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* T1_MOTOR_PROTOCOL_H */
