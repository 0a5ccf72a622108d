/* MAVLink framing checks: CRC-16/MCRF4XX with CRC_EXTRA, and whether a datagram is a run of clean
 * frames (mavscope/mavlink/framing.py). */
#ifndef MAVSCOPE_NATIVE_MAVLINK_H
#define MAVSCOPE_NATIVE_MAVLINK_H

#include <stddef.h>
#include <stdint.h>

#define MS_STX_V1 0xFE
#define MS_STX_V2 0xFD
#define MS_HEADER_V1 6
#define MS_HEADER_V2 10
#define MS_SIGNATURE_LEN 13

extern const uint16_t MS_CRC_TABLE[256];

/* CRC-16/MCRF4XX (X.25: poly 0x1021 reflected, no final xor) of n bytes, continuing from crc (0xFFFF to start) */
static inline uint16_t ms_crc16(const uint8_t *p, size_t n, uint16_t crc) {
    for (size_t i = 0; i < n; i++)
        crc = (uint16_t)((crc >> 8) ^ MS_CRC_TABLE[(crc ^ p[i]) & 0xFF]);
    return crc;
}

#endif
