/*
 * t1_firmware.h — the motor-driver firmware API: frame codec, per-motor step, CAN bus model, and batch
 * helpers for the simulator. The protocol itself (ids, packing, ranges, status bits) is documented in
 * t1_motor_protocol.h. C99, no heap: every state is a plain struct the caller owns.
 *
 * Error convention: functions that can fail return int: T1_OK (0) or a negative T1_ERR_*.
 */
#ifndef T1_FIRMWARE_H
#define T1_FIRMWARE_H

#include <stddef.h>
#include <stdint.h>

#include "t1_motor_protocol.h"

#ifdef __cplusplus
extern "C" {
#endif

#define T1_OK 0
#define T1_ERR_NONFINITE (-1) /* a float input was NaN or ±inf */
#define T1_ERR_BAD_INDEX (-2) /* motor index outside 0..22 / bus index outside 0..3 */
#define T1_ERR_BAD_DLC (-3)   /* frame length differs from the protocol's */
#define T1_ERR_BAD_ID (-4)    /* CAN id / motor id byte not the expected one */
#define T1_ERR_NULL (-5)      /* a required pointer was NULL */

/* Human-readable name of a T1_OK / T1_ERR_* code (static string). */
const char* t1_error_name(int code);

/* ================================ codec ================================ */

typedef struct {
  float q_des_rad;
  float dq_des_rads;
  float kp_nm_per_rad;
  float kd_nms_per_rad;
  float tau_ff_nm;
} t1_command_t;

typedef struct {
  uint8_t motor_id; /* 1..23 */
  float q_rad;
  float dq_rads;
  float tau_nm;
  uint8_t status; /* T1_STATUS_* bits */
} t1_reply_t;

/* Fixed-point helpers (§5 of the protocol header). x must be finite; beyond [lo, hi] → edge code. */
uint32_t t1_float_to_code(float x, float lo, float hi, unsigned bits);
float t1_code_to_float(uint32_t code, float lo, float hi, unsigned bits);

/* Encode a command for motor `motor_index` (0..22) into out[0..7]. Values beyond a range saturate to
 * the edge. Any non-finite field → T1_ERR_NONFINITE and out is left untouched (nothing to send). */
int t1_pack_command(unsigned motor_index, const t1_command_t* cmd, uint8_t out[T1_CMD_DLC]);
/* Decode a command frame's data bytes for motor `motor_index`. dlc must be T1_CMD_DLC. */
int t1_unpack_command(unsigned motor_index, const uint8_t* data, uint8_t dlc, t1_command_t* out);

/* Encode a reply. Non-finite q/dq/tau are encoded as 0 and T1_STATUS_BAD_SENSOR is OR-ed into the
 * status byte, so a bad value never reaches the host as a number. Returns T1_OK or an error. */
int t1_pack_reply(unsigned motor_index, float q_rad, float dq_rads, float tau_nm, uint8_t status,
                  uint8_t out[T1_REPLY_DLC]);
/* Decode a reply frame's data bytes (dlc must be T1_REPLY_DLC, motor id byte 1..23). */
int t1_unpack_reply(const uint8_t* data, uint8_t dlc, t1_reply_t* out);

/* Range of the velocity / torque fields for a motor (its class's range). */
float t1_motor_v_max_rads(unsigned motor_index);
float t1_motor_t_max_nm(unsigned motor_index);

/* ================================ motor ================================ */

typedef struct {
  uint8_t motor_index;     /* 0..22 */
  uint8_t has_command;     /* a valid command was ever received (0 = power-on state) */
  uint8_t bad_frame_latch; /* T1_STATUS_BAD_FRAME until the next valid command */
  uint8_t status;          /* status bits of the last step (+ latch), sent in the reply */
  uint64_t last_command_us;
  t1_command_t command; /* the latched (decoded) command */
  float last_tau_nm;    /* torque applied in the last step */
} t1_motor_t;

/* Power-on reset: no command, damping, status POWER_ON | DAMPING. */
int t1_motor_init(t1_motor_t* m, unsigned motor_index);

/* Validate and latch a received frame. can_id must be this motor's command id and dlc T1_CMD_DLC;
 * otherwise BAD_FRAME is latched, the previous command stays in force and the error is returned. */
int t1_motor_receive(t1_motor_t* m, uint32_t can_id, const uint8_t* data, uint8_t dlc, uint64_t now_us);

/* One firmware step at time now_us with measured q [rad], dq [rad/s]: returns the torque [N·m] to
 * apply (already clamped) and updates m->status. See §6 of the protocol header. */
float t1_motor_step(t1_motor_t* m, float q_rad, float dq_rads, uint64_t now_us);

/* Build this motor's reply from measured q, dq and the applied torque; returns the DLC (7) or an
 * error. */
int t1_motor_reply(const t1_motor_t* m, float q_rad, float dq_rads, float tau_nm, uint8_t out[T1_FRAME_SLOT_BYTES]);

/* ================================ CAN bus model ================================ */

/* Bits on the wire for one CAN 2.0A data frame, exactly: SOF, 11-bit id, RTR, IDE, r0, DLC, data and
 * the real CRC-15 with bit stuffing computed on the actual bits, then CRC delimiter, ACK slot, ACK
 * delimiter, 7-bit EOF and the 3-bit intermission (IFS). Returns 0 for an invalid id (> 0x7FF) or
 * dlc (> 8). */
uint32_t t1_can_frame_bits(uint32_t can_id, const uint8_t* data, uint8_t dlc);
/* Number of stuff bits inserted over SOF..CRC for this frame (part of t1_can_frame_bits). */
uint32_t t1_can_stuff_bits(uint32_t can_id, const uint8_t* data, uint8_t dlc);
/* CAN CRC-15 (polynomial 0x4599, initial 0) over nbits bits, bits[i] ∈ {0,1}, MSB first. */
uint16_t t1_can_crc15_bits(const uint8_t* bits, size_t nbits);

#define T1_BUS_LATE 0
#define T1_BUS_ON_TIME 1

typedef struct {
  uint8_t bus_index;
  uint32_t capacity_bits;   /* bitrate × cycle period */
  uint64_t cycle_start_us;  /* time given to the last begin_cycle */
  uint32_t bits_this_cycle; /* offered bits since begin_cycle (may exceed capacity) */
  uint32_t bits_last_cycle; /* offered bits of the previous, completed cycle */
  uint32_t frames_this_cycle;
  uint32_t late_this_cycle;
  uint64_t frames_total;
  uint64_t frames_late_total;
} t1_bus_t;

int t1_bus_init(t1_bus_t* bus, unsigned bus_index, uint32_t bitrate_bps, uint32_t cycle_us);
/* Close the running cycle (its bits become bits_last_cycle) and start a new one at now_us. */
void t1_bus_begin_cycle(t1_bus_t* bus, uint64_t now_us);
/* Queue one frame in the running cycle: T1_BUS_ON_TIME if its last bit ends within the cycle's
 * capacity, T1_BUS_LATE if not (counted in late_this_cycle / frames_late_total), negative on an
 * invalid id / dlc. */
int t1_bus_submit(t1_bus_t* bus, uint32_t can_id, const uint8_t* data, uint8_t dlc);
/* Utilisation of the last completed cycle: bits_last_cycle / capacity (> 1 means overload). */
float t1_bus_utilisation(const t1_bus_t* bus);

/* ================================ batch helpers (one call per tick) ================================
 * Arrays are in joint order, length T1_NUM_MOTORS; frame buffers hold T1_NUM_MOTORS slots of
 * T1_FRAME_SLOT_BYTES. Inputs are double (numpy float64); the firmware computes in float. */

typedef struct {
  t1_motor_t motors[T1_NUM_MOTORS];
} t1_motor_array_t;

typedef struct {
  t1_bus_t buses[T1_NUM_BUSES];
} t1_bus_array_t;

size_t t1_motor_array_size(void);
size_t t1_bus_array_size(void);
void t1_motor_array_init(t1_motor_array_t* a);
int t1_bus_array_init(t1_bus_array_t* b);

/* Pack all 23 commands into out. Returns a bit mask of motors whose command had a non-finite field
 * (their slot is zeroed and must not be sent); 0 = all packed. */
uint32_t t1_batch_pack_commands(const double* q_des, const double* dq_des, const double* kp, const double* kd,
                                const double* tau_ff, uint8_t* out);
/* Deliver slot i to motor i for every bit set in deliver_mask (1 << i), as a command with the
 * motor's own id and DLC 8. Returns the mask of frames rejected. */
uint32_t t1_batch_receive(t1_motor_array_t* a, const uint8_t* frames, uint32_t deliver_mask, uint64_t now_us);
/* Step all 23 motors; tau_out[i] in N·m. */
void t1_batch_step(t1_motor_array_t* a, const double* q, const double* dq, uint64_t now_us, double* tau_out);
/* Build all 23 replies (slot byte 7 = 0). */
void t1_batch_replies(const t1_motor_array_t* a, const double* q, const double* dq, const double* tau, uint8_t* out);
/* Status reported for a reply slot that does not decode: every bit set, so no "healthy" reading. */
#define T1_BATCH_NO_REPLY_STATUS (-1)
/* Decode all 23 reply slots. Returns the mask of slots that failed to decode (wrong motor id byte for
 * the slot); their outputs are NaN and status T1_BATCH_NO_REPLY_STATUS. */
uint32_t t1_batch_unpack_replies(const uint8_t* frames, double* q, double* dq, double* tau, int32_t* status);
/* Decode all 23 command slots (for tests / logging). */
void t1_batch_unpack_commands(const uint8_t* frames, double* q_des, double* dq_des, double* kp, double* kd,
                              double* tau_ff);
/* Current status bits of all motors. */
void t1_batch_status(const t1_motor_array_t* a, int32_t* status);
/* One bus cycle on all 4 buses: begin_cycle(now_us), then every command (in id order, they win
 * arbitration), then every reply, each on its motor's bus. cmd_on_time / reply_on_time receive 1 or 0
 * per motor. Only motors set in cmd_mask send a command (a motor still replies every cycle). */
void t1_batch_bus_cycle(t1_bus_array_t* b, uint64_t now_us, const uint8_t* commands, uint32_t cmd_mask,
                        const uint8_t* replies, uint8_t* cmd_on_time, uint8_t* reply_on_time);

/* ================================ host link (the simulator's in-process buses) ================================
 * The 4 buses between the host and the 23 motors for one control tick, in two calls: what sim_hil's python-can
 * MotorBus does frame by frame, without a Python object per frame. Every frame is counted by its bus model;
 * a frame that does not fit in its cycle (T1_BUS_LATE) goes out first in the next cycle; a delayed command
 * waits its cycles in a FIFO; a frame lost on the wire is never submitted. Masks: bit i = motor i. */

#define T1_LINK_LATE_CAPACITY 128u   /* frames carried per bus (overload beyond it: the frame is lost) */
#define T1_LINK_DELAY_CAPACITY 1024u /* delayed frames in flight (a 3-cycle delay of all 23 holds 69) */

typedef struct {
  uint32_t can_id;
  uint32_t due_cycle; /* delayed frames: the cycle they go on the wire */
  uint8_t bus;
  uint8_t dlc;
  uint8_t data[T1_FRAME_SLOT_BYTES];
} t1_link_frame_t;

typedef struct {
  t1_bus_t buses[T1_NUM_BUSES];
  t1_link_frame_t late[T1_NUM_BUSES][T1_LINK_LATE_CAPACITY];
  uint32_t n_late[T1_NUM_BUSES];
  t1_link_frame_t delayed[T1_LINK_DELAY_CAPACITY]; /* ring buffer, oldest first */
  uint32_t delayed_head, n_delayed;
  uint32_t cycle;                                        /* completed cycles (one per exchange_replies) */
  uint8_t motor_rx[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES]; /* newest command that reached each motor */
  uint32_t motor_rx_mask;
  uint8_t host_rx[T1_NUM_MOTORS * T1_FRAME_SLOT_BYTES]; /* newest reply that reached the host */
  uint32_t host_rx_mask;
  uint64_t frames_sent, frames_dropped, frames_lost_overflow;
} t1_link_t;

size_t t1_link_size(void);
int t1_link_init(t1_link_t* l);
/* Host → motors, opening the cycle at now_us: last cycle's late frames first, then motor i's command
 * (slot i of `frames`) for each bit of send_mask — lost if set in drop_mask, held delay_cycles cycles if
 * > 0 — then the delayed frames now due. Each motor not in dead_mask latches the newest command that
 * reached it. Returns the mask of motors that latched one this cycle. */
uint32_t t1_link_send_commands(t1_link_t* l, t1_motor_array_t* motors, uint64_t now_us, const uint8_t* frames,
                               uint32_t send_mask, uint32_t drop_mask, uint32_t delay_cycles, uint32_t dead_mask);
/* Motors → host, closing the cycle: motor i's reply (slot i of `replies`) for each bit of send_mask, lost
 * if set in drop_mask. Copies every reply the host received this cycle (late ones from the last cycle
 * included) into host_frames and returns their mask. */
uint32_t t1_link_exchange_replies(t1_link_t* l, const uint8_t* replies, uint32_t send_mask, uint32_t drop_mask,
                                  uint8_t* host_frames);
/* The host's joint view after a cycle: each motor in `got` takes its reply's q, dq, tau and status (a slot
 * that does not decode: NaN and T1_BATCH_NO_REPLY_STATUS); every other motor keeps its last values with
 * T1_STATUS_NO_REPLY added to its status. */
void t1_host_view_update(const uint8_t* host_frames, uint32_t got, double* q, double* dq, double* tau, int32_t* status);
/* out = {frames_sent, frames_dropped, frames_lost_overflow}. */
void t1_link_counters(const t1_link_t* l, uint64_t out[3]);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* T1_FIRMWARE_H */
