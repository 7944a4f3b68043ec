/* Byte-wise lookup tables of the CAN bus model (generated: t1_can_tables.c, tools/gen_can_tables.py). */
#ifndef T1_CAN_TABLES_H
#define T1_CAN_TABLES_H

#include <stdint.h>

/* CRC-15 (poly 0x4599) byte step, MSB first: crc = ((crc << 8) & 0x7FFF) ^ T[((crc >> 7) ^ byte) & 0xFF]. */
extern const uint16_t T1_CAN_CRC15_TABLE[256];
/* Stuffing: state = run_value << 2 | (run_length - 1), run_length 1..4; entry = stuff_bits << 3 | state'. */
extern const uint8_t T1_CAN_STUFF_TABLE[8][256];
#define T1_CAN_STUFF_STATE_MASK 0x7u
#define T1_CAN_STUFF_COUNT_SHIFT 3u

#endif /* T1_CAN_TABLES_H */
