/* JSON text of numbers and strings, byte-identical to orjson's output (docs/native.md).
 *
 * - integers in decimal;
 * - doubles as the shortest text that reads back to the same double (Ryu), laid out as orjson does:
 *   fixed notation with at least one decimal (`1.0`, `-0.0`, `0.00001`) while the decimal exponent is
 *   in [-5, 16), else `1e+16`, `1.5e-7`; NaN and infinities as `null`; float32 values (MAVLink `float`)
 *   as the shortest text that reads back to the same float32 (Ryu's f2s), in the same layout;
 * - strings from bytes as mavscope's Python path makes them (`bytes.decode("utf-8", "backslashreplace")`,
 *   invalid bytes as `\xNN`), then escaped as orjson escapes (`\"`, `\\`, `\n`..., other control
 *   characters `\u00XX`; everything else as UTF-8).
 *
 * The ms_w_* writers write at `p` and return the end: the caller has made room for the most each can
 * write (MS_U64_MAX, MS_DOUBLE_MAX, ms_text_max(n)). The ms_put_* ones grow an ms_buf first. */
#ifndef MAVSCOPE_NATIVE_FMT_H
#define MAVSCOPE_NATIVE_FMT_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "buf.h"

#define MS_U64_MAX 20    /* 18446744073709551615 */
#define MS_I64_MAX 20    /* -9223372036854775808 */
/* The longest double text is 24 bytes (-1.2345678901234567e-308); ms_w_double's fixed-size copies write
 * up to 40 bytes past p (sign, x + 2 <= 17, then 16 more digits; or 7 + 20): room for 48. */
#define MS_DOUBLE_MAX 48

extern const char MS_DIGIT_PAIRS[200];
/* MS_U8_TEXT[v]: the decimal text of v in the first bytes, its length in the last one */
extern const char MS_U8_TEXT[256][4];

/* Decimal text of a byte; writes 4 bytes (room for 4), returns the end of the text. */
static inline char *ms_w_u8(char *p, unsigned v) {
    memcpy(p, MS_U8_TEXT[v & 0xFF], 4);
    return p + MS_U8_TEXT[v & 0xFF][3];
}

/* Decimal text of v < 10**8 in exactly 8 digits (leading zeros). */
static inline char *ms_w_8digits(char *p, uint32_t v) {
    uint32_t hi = v / 10000, lo = v % 10000;
    memcpy(p, MS_DIGIT_PAIRS + 2 * (hi / 100), 2);
    memcpy(p + 2, MS_DIGIT_PAIRS + 2 * (hi % 100), 2);
    memcpy(p + 4, MS_DIGIT_PAIRS + 2 * (lo / 100), 2);
    memcpy(p + 6, MS_DIGIT_PAIRS + 2 * (lo % 100), 2);
    return p + 8;
}

static inline char *ms_w_u32(char *p, uint32_t v) {
    if (v < 10) {
        *p = (char)('0' + v);
        return p + 1;
    }
    if (v < 100) {
        memcpy(p, MS_DIGIT_PAIRS + 2 * v, 2);
        return p + 2;
    }
    int n = v < 1000 ? 3 : v < 10000 ? 4 : v < 100000 ? 5 : v < 1000000 ? 6 : v < 10000000 ? 7
          : v < 100000000 ? 8 : v < 1000000000 ? 9 : 10;
    char *end = p + n, *q = end;
    while (v >= 100) {
        uint32_t r = v % 100;
        v /= 100;
        q -= 2;
        memcpy(q, MS_DIGIT_PAIRS + 2 * r, 2);
    }
    if (v >= 10) {
        q -= 2;
        memcpy(q, MS_DIGIT_PAIRS + 2 * v, 2);
    } else {
        *--q = (char)('0' + v);
    }
    return end;
}

static inline char *ms_w_u64(char *p, uint64_t v) {
    if (v <= UINT32_MAX)
        return ms_w_u32(p, (uint32_t)v);
    uint64_t hi = v / 100000000;
    uint32_t lo = (uint32_t)(v % 100000000);
    if (hi <= UINT32_MAX) {
        p = ms_w_u32(p, (uint32_t)hi);
    } else {
        p = ms_w_u32(p, (uint32_t)(hi / 100000000));
        p = ms_w_8digits(p, (uint32_t)(hi % 100000000));
    }
    return ms_w_8digits(p, lo);
}

static inline char *ms_w_i64(char *p, int64_t v) {
    if (v < 0) {
        *p++ = '-';
        return ms_w_u64(p, (uint64_t)(-(v + 1)) + 1u); /* no overflow for INT64_MIN */
    }
    return ms_w_u64(p, (uint64_t)v);
}

#define MS_W_LIT(p, lit) (memcpy((p), (lit), sizeof(lit) - 1), (p) + sizeof(lit) - 1)

char *ms_w_double(char *p, double v);
/* A float32 as JSON: the shortest decimal that reads back as the same float32 (Ryu's f2s: 30.48, not the
 * widened double's 30.479999542236328), laid out as ms_w_double lays out a double; NaN and infinities null.
 * Room: MS_DOUBLE_MAX. */
char *ms_w_f32(char *p, float v);
/* Python's repr of a double (finite: NaN and infinities are the caller's), and the same layout of the
 * shortest float32 decimal (mavscope/mavlink/floats.py f32_text): `30.48`, `100.0`, `1e-05`. Room:
 * MS_REPR_MAX. */
#define MS_REPR_MAX 32 /* -1.2345678901234567e-308: 24 */
char *ms_w_double_repr(char *p, double v);
char *ms_w_f32_repr(char *p, float v);

/* The most ms_w_text writes for n input bytes: 6 per byte (\u00XX) and the quotes. */
static inline size_t ms_text_max(size_t n) { return 6 * n + 2; }
/* A JSON string (quotes included) of `n` bytes decoded as UTF-8 with backslashreplace. */
char *ms_w_text(char *p, const uint8_t *s, size_t n);

/* Text into a small array (tests and notes). */
int ms_fmt_double(double v, char *out);
int ms_fmt_u64(uint64_t v, char *out);

void ms_put_u64(ms_buf *b, uint64_t v);
void ms_put_double(ms_buf *b, double v);
void ms_put_text(ms_buf *b, const uint8_t *s, size_t n);

#endif
