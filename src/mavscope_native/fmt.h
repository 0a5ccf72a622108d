/* JSON text of numbers and strings, byte-identical to orjson's output (docs/native.md).
 *
 * - integers in decimal;
 * - doubles as the shortest text that reads back to the same double (Ryu), laid out as orjson does:
 *   fixed notation with at least one decimal (`1.0`, `-0.0`, `0.00001`) while the decimal exponent is
 *   in [-5, 16), else `1e+16`, `1.5e-7`; NaN and infinities as `null`;
 * - strings from bytes as mavscope's Python path makes them (`bytes.decode("utf-8", "backslashreplace")`,
 *   invalid bytes as `\xNN`), then escaped as orjson escapes (`\"`, `\\`, `\n`..., other control
 *   characters `\u00XX`; everything else as UTF-8). */
#ifndef MAVSCOPE_NATIVE_FMT_H
#define MAVSCOPE_NATIVE_FMT_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"

#define MS_DOUBLE_MAX 32 /* longest text ms_fmt_double writes: -1.2345678901234567e-308 is 24 */

/* Write the JSON text of `v` to `out` (room for MS_DOUBLE_MAX bytes); returns its length. */
int ms_fmt_double(double v, char *out);
/* Decimal text of `v` (room for 20 bytes); returns its length. */
int ms_fmt_u64(uint64_t v, char *out);
int ms_fmt_i64(int64_t v, char *out);

void ms_put_u64(ms_buf *b, uint64_t v);
void ms_put_i64(ms_buf *b, int64_t v);
void ms_put_double(ms_buf *b, double v);
/* A JSON string (quotes included) of `n` bytes decoded as UTF-8 with backslashreplace. */
void ms_put_text(ms_buf *b, const uint8_t *s, size_t n);

#endif
