/* MAVLink framing: CRC-16/MCRF4XX with CRC_EXTRA (mavscope/mavlink/framing.py). */
#ifndef MAVSCOPE_NATIVE_MAVLINK_H
#define MAVSCOPE_NATIVE_MAVLINK_H

#include <stddef.h>
#include <stdint.h>

#define MS_STX_V1 0xFE
#define MS_STX_V2 0xFD
#define MS_HEADER_V1 6
#define MS_HEADER_V2 10
#define MS_SIGNATURE_LEN 13

/* MS_CRC_TABLE[k][i]: the CRC state change of byte i followed by k zero bytes (slicing-by-8) */
extern const uint16_t MS_CRC_TABLE[8][256];

/* CRC-16/MCRF4XX (X.25: poly 0x1021 reflected, no final xor) of n bytes, continuing from crc (0xFFFF to
 * start), eight bytes per step. */
static inline uint16_t ms_crc16(const uint8_t *p, size_t n, uint16_t crc) {
    const uint16_t(*t)[256] = MS_CRC_TABLE;
    while (n >= 8) {
        const unsigned x = crc ^ (unsigned)(p[0] | (p[1] << 8));
        crc = (uint16_t)(t[7][x & 0xFF] ^ t[6][x >> 8] ^ t[5][p[2]] ^ t[4][p[3]] ^ t[3][p[4]] ^ t[2][p[5]] ^
                         t[1][p[6]] ^ t[0][p[7]]);
        p += 8;
        n -= 8;
    }
    while (n--)
        crc = (uint16_t)((crc >> 8) ^ t[0][(crc ^ *p++) & 0xFF]);
    return crc;
}

#endif
