#include "fmt.h"

#include <string.h>

#include "vendor/ryu/ryu_d2d.h"
#include "vendor/ryu/ryu_f2d.h"

const char MS_DIGIT_PAIRS[200] = {
    '0', '0', '0', '1', '0', '2', '0', '3', '0', '4', '0', '5', '0', '6', '0', '7', '0', '8', '0', '9',
    '1', '0', '1', '1', '1', '2', '1', '3', '1', '4', '1', '5', '1', '6', '1', '7', '1', '8', '1', '9',
    '2', '0', '2', '1', '2', '2', '2', '3', '2', '4', '2', '5', '2', '6', '2', '7', '2', '8', '2', '9',
    '3', '0', '3', '1', '3', '2', '3', '3', '3', '4', '3', '5', '3', '6', '3', '7', '3', '8', '3', '9',
    '4', '0', '4', '1', '4', '2', '4', '3', '4', '4', '4', '5', '4', '6', '4', '7', '4', '8', '4', '9',
    '5', '0', '5', '1', '5', '2', '5', '3', '5', '4', '5', '5', '5', '6', '5', '7', '5', '8', '5', '9',
    '6', '0', '6', '1', '6', '2', '6', '3', '6', '4', '6', '5', '6', '6', '6', '7', '6', '8', '6', '9',
    '7', '0', '7', '1', '7', '2', '7', '3', '7', '4', '7', '5', '7', '6', '7', '7', '7', '8', '7', '9',
    '8', '0', '8', '1', '8', '2', '8', '3', '8', '4', '8', '5', '8', '6', '8', '7', '8', '8', '8', '9',
    '9', '0', '9', '1', '9', '2', '9', '3', '9', '4', '9', '5', '9', '6', '9', '7', '9', '8', '9', '9',
};

/* generated: the text of 0..255, padded with NULs, its length last */
const char MS_U8_TEXT[256][4] = {
    {'0', 0, 0, 1}, {'1', 0, 0, 1}, {'2', 0, 0, 1}, {'3', 0, 0, 1}, {'4', 0, 0, 1}, {'5', 0, 0, 1},
    {'6', 0, 0, 1}, {'7', 0, 0, 1}, {'8', 0, 0, 1}, {'9', 0, 0, 1}, {'1', '0', 0, 2}, {'1', '1', 0, 2},
    {'1', '2', 0, 2}, {'1', '3', 0, 2}, {'1', '4', 0, 2}, {'1', '5', 0, 2}, {'1', '6', 0, 2}, {'1', '7', 0, 2},
    {'1', '8', 0, 2}, {'1', '9', 0, 2}, {'2', '0', 0, 2}, {'2', '1', 0, 2}, {'2', '2', 0, 2}, {'2', '3', 0, 2},
    {'2', '4', 0, 2}, {'2', '5', 0, 2}, {'2', '6', 0, 2}, {'2', '7', 0, 2}, {'2', '8', 0, 2}, {'2', '9', 0, 2},
    {'3', '0', 0, 2}, {'3', '1', 0, 2}, {'3', '2', 0, 2}, {'3', '3', 0, 2}, {'3', '4', 0, 2}, {'3', '5', 0, 2},
    {'3', '6', 0, 2}, {'3', '7', 0, 2}, {'3', '8', 0, 2}, {'3', '9', 0, 2}, {'4', '0', 0, 2}, {'4', '1', 0, 2},
    {'4', '2', 0, 2}, {'4', '3', 0, 2}, {'4', '4', 0, 2}, {'4', '5', 0, 2}, {'4', '6', 0, 2}, {'4', '7', 0, 2},
    {'4', '8', 0, 2}, {'4', '9', 0, 2}, {'5', '0', 0, 2}, {'5', '1', 0, 2}, {'5', '2', 0, 2}, {'5', '3', 0, 2},
    {'5', '4', 0, 2}, {'5', '5', 0, 2}, {'5', '6', 0, 2}, {'5', '7', 0, 2}, {'5', '8', 0, 2}, {'5', '9', 0, 2},
    {'6', '0', 0, 2}, {'6', '1', 0, 2}, {'6', '2', 0, 2}, {'6', '3', 0, 2}, {'6', '4', 0, 2}, {'6', '5', 0, 2},
    {'6', '6', 0, 2}, {'6', '7', 0, 2}, {'6', '8', 0, 2}, {'6', '9', 0, 2}, {'7', '0', 0, 2}, {'7', '1', 0, 2},
    {'7', '2', 0, 2}, {'7', '3', 0, 2}, {'7', '4', 0, 2}, {'7', '5', 0, 2}, {'7', '6', 0, 2}, {'7', '7', 0, 2},
    {'7', '8', 0, 2}, {'7', '9', 0, 2}, {'8', '0', 0, 2}, {'8', '1', 0, 2}, {'8', '2', 0, 2}, {'8', '3', 0, 2},
    {'8', '4', 0, 2}, {'8', '5', 0, 2}, {'8', '6', 0, 2}, {'8', '7', 0, 2}, {'8', '8', 0, 2}, {'8', '9', 0, 2},
    {'9', '0', 0, 2}, {'9', '1', 0, 2}, {'9', '2', 0, 2}, {'9', '3', 0, 2}, {'9', '4', 0, 2}, {'9', '5', 0, 2},
    {'9', '6', 0, 2}, {'9', '7', 0, 2}, {'9', '8', 0, 2}, {'9', '9', 0, 2}, {'1', '0', '0', 3}, {'1', '0', '1', 3},
    {'1', '0', '2', 3}, {'1', '0', '3', 3}, {'1', '0', '4', 3}, {'1', '0', '5', 3}, {'1', '0', '6', 3}, {'1', '0', '7', 3},
    {'1', '0', '8', 3}, {'1', '0', '9', 3}, {'1', '1', '0', 3}, {'1', '1', '1', 3}, {'1', '1', '2', 3}, {'1', '1', '3', 3},
    {'1', '1', '4', 3}, {'1', '1', '5', 3}, {'1', '1', '6', 3}, {'1', '1', '7', 3}, {'1', '1', '8', 3}, {'1', '1', '9', 3},
    {'1', '2', '0', 3}, {'1', '2', '1', 3}, {'1', '2', '2', 3}, {'1', '2', '3', 3}, {'1', '2', '4', 3}, {'1', '2', '5', 3},
    {'1', '2', '6', 3}, {'1', '2', '7', 3}, {'1', '2', '8', 3}, {'1', '2', '9', 3}, {'1', '3', '0', 3}, {'1', '3', '1', 3},
    {'1', '3', '2', 3}, {'1', '3', '3', 3}, {'1', '3', '4', 3}, {'1', '3', '5', 3}, {'1', '3', '6', 3}, {'1', '3', '7', 3},
    {'1', '3', '8', 3}, {'1', '3', '9', 3}, {'1', '4', '0', 3}, {'1', '4', '1', 3}, {'1', '4', '2', 3}, {'1', '4', '3', 3},
    {'1', '4', '4', 3}, {'1', '4', '5', 3}, {'1', '4', '6', 3}, {'1', '4', '7', 3}, {'1', '4', '8', 3}, {'1', '4', '9', 3},
    {'1', '5', '0', 3}, {'1', '5', '1', 3}, {'1', '5', '2', 3}, {'1', '5', '3', 3}, {'1', '5', '4', 3}, {'1', '5', '5', 3},
    {'1', '5', '6', 3}, {'1', '5', '7', 3}, {'1', '5', '8', 3}, {'1', '5', '9', 3}, {'1', '6', '0', 3}, {'1', '6', '1', 3},
    {'1', '6', '2', 3}, {'1', '6', '3', 3}, {'1', '6', '4', 3}, {'1', '6', '5', 3}, {'1', '6', '6', 3}, {'1', '6', '7', 3},
    {'1', '6', '8', 3}, {'1', '6', '9', 3}, {'1', '7', '0', 3}, {'1', '7', '1', 3}, {'1', '7', '2', 3}, {'1', '7', '3', 3},
    {'1', '7', '4', 3}, {'1', '7', '5', 3}, {'1', '7', '6', 3}, {'1', '7', '7', 3}, {'1', '7', '8', 3}, {'1', '7', '9', 3},
    {'1', '8', '0', 3}, {'1', '8', '1', 3}, {'1', '8', '2', 3}, {'1', '8', '3', 3}, {'1', '8', '4', 3}, {'1', '8', '5', 3},
    {'1', '8', '6', 3}, {'1', '8', '7', 3}, {'1', '8', '8', 3}, {'1', '8', '9', 3}, {'1', '9', '0', 3}, {'1', '9', '1', 3},
    {'1', '9', '2', 3}, {'1', '9', '3', 3}, {'1', '9', '4', 3}, {'1', '9', '5', 3}, {'1', '9', '6', 3}, {'1', '9', '7', 3},
    {'1', '9', '8', 3}, {'1', '9', '9', 3}, {'2', '0', '0', 3}, {'2', '0', '1', 3}, {'2', '0', '2', 3}, {'2', '0', '3', 3},
    {'2', '0', '4', 3}, {'2', '0', '5', 3}, {'2', '0', '6', 3}, {'2', '0', '7', 3}, {'2', '0', '8', 3}, {'2', '0', '9', 3},
    {'2', '1', '0', 3}, {'2', '1', '1', 3}, {'2', '1', '2', 3}, {'2', '1', '3', 3}, {'2', '1', '4', 3}, {'2', '1', '5', 3},
    {'2', '1', '6', 3}, {'2', '1', '7', 3}, {'2', '1', '8', 3}, {'2', '1', '9', 3}, {'2', '2', '0', 3}, {'2', '2', '1', 3},
    {'2', '2', '2', 3}, {'2', '2', '3', 3}, {'2', '2', '4', 3}, {'2', '2', '5', 3}, {'2', '2', '6', 3}, {'2', '2', '7', 3},
    {'2', '2', '8', 3}, {'2', '2', '9', 3}, {'2', '3', '0', 3}, {'2', '3', '1', 3}, {'2', '3', '2', 3}, {'2', '3', '3', 3},
    {'2', '3', '4', 3}, {'2', '3', '5', 3}, {'2', '3', '6', 3}, {'2', '3', '7', 3}, {'2', '3', '8', 3}, {'2', '3', '9', 3},
    {'2', '4', '0', 3}, {'2', '4', '1', 3}, {'2', '4', '2', 3}, {'2', '4', '3', 3}, {'2', '4', '4', 3}, {'2', '4', '5', 3},
    {'2', '4', '6', 3}, {'2', '4', '7', 3}, {'2', '4', '8', 3}, {'2', '4', '9', 3}, {'2', '5', '0', 3}, {'2', '5', '1', 3},
    {'2', '5', '2', 3}, {'2', '5', '3', 3}, {'2', '5', '4', 3}, {'2', '5', '5', 3},
};

int ms_fmt_u64(uint64_t v, char *out) { return (int)(ms_w_u64(out, v) - out); }

static const uint64_t POW10[20] = {
    1ull, 10ull, 100ull, 1000ull, 10000ull, 100000ull, 1000000ull, 10000000ull, 100000000ull, 1000000000ull,
    10000000000ull, 100000000000ull, 1000000000000ull, 10000000000000ull, 100000000000000ull,
    1000000000000000ull, 10000000000000000ull, 100000000000000000ull, 1000000000000000000ull,
    10000000000000000000ull,
};

/* All 20 decimal digits of v (leading zeros) in buf[0..20), '0' in buf[20..64); returns how many digits v
 * has (1..20), so its text is buf + 20 - n. Three independent 8-digit conversions instead of a loop. */
static inline int digits20(uint64_t v, char buf[64]) {
    memset(buf + 20, '0', 44);
    const uint64_t a = v / 10000000000000000ull; /* <= 1844 */
    const uint64_t rest = v % 10000000000000000ull;
    memcpy(buf, MS_DIGIT_PAIRS + 2 * (a / 100), 2);
    memcpy(buf + 2, MS_DIGIT_PAIRS + 2 * (a % 100), 2);
    ms_w_8digits(buf + 4, (uint32_t)(rest / 100000000));
    ms_w_8digits(buf + 12, (uint32_t)(rest % 100000000));
    const int bits = 64 - __builtin_clzll(v | 1);
    const int t = (bits * 1233) >> 12; /* floor(log10(2**bits)) */
    return t + (v >= POW10[t]);
}

/* digits[0..n) * 10^k (n <= 17, digits readable 20 bytes on) laid out as orjson lays out a double */
static char *w_json_layout(char *p, const char *digits, int n, int k) {
    const int x = n + k - 1;     /* value = d.ddd * 10^x */
    if (x >= -5 && x < 16) {
        if (k >= 0) { /* 1230000.0: the digits, k zeros (n + k <= 16), ".0" */
            memcpy(p, digits, 16);
            memset(p + n, '0', 16);
            p += n + k;
            memcpy(p, ".0", 2);
            return p + 2;
        }
        if (x >= 0) { /* 12.34: x + 1 <= 16 digits, the point, the other n - x - 1 <= 16 */
            memcpy(p, digits, 16);
            p[x + 1] = '.';
            memcpy(p + x + 2, digits + x + 1, 16);
            return p + n + 1;
        }
        /* 0.00123: "0." then -x - 1 <= 4 zeros, then the digits */
        memcpy(p, "0.0000", 6);
        memcpy(p + 1 - x, digits, 20);
        return p + 1 - x + n;
    }
    /* 1.23e+16, 1e-7 */
    p[0] = digits[0];
    if (n > 1) {
        p[1] = '.';
        memcpy(p + 2, digits + 1, 16);
        p += n + 1;
    } else {
        p += 1;
    }
    *p++ = 'e';
    int e = x;
    if (e < 0) {
        *p++ = '-';
        e = -e;
    } else {
        *p++ = '+';
    }
    if (e >= 100) {
        *p++ = (char)('0' + e / 100);
        e %= 100;
        memcpy(p, MS_DIGIT_PAIRS + 2 * e, 2);
        return p + 2;
    }
    if (e >= 10) {
        memcpy(p, MS_DIGIT_PAIRS + 2 * e, 2);
        return p + 2;
    }
    *p++ = (char)('0' + e);
    return p;
}

/* digits[0..n) * 10^k laid out as Python's repr lays out a float: fixed notation for decimal exponents
 * -4..15 with at least one decimal (`100.0`, `0.0001`), else `1e-05`, `3.4028235e+38` (two exponent digits
 * at least) */
static char *w_repr_layout(char *p, const char *digits, int n, int k) {
    const int x = n + k - 1;
    if (x >= -4 && x < 16) {
        if (k >= 0) {
            memcpy(p, digits, (size_t)n);
            memset(p + n, '0', (size_t)k);
            p += n + k;
            memcpy(p, ".0", 2);
            return p + 2;
        }
        if (x >= 0) {
            memcpy(p, digits, (size_t)x + 1);
            p[x + 1] = '.';
            memcpy(p + x + 2, digits + x + 1, (size_t)(n - x - 1));
            return p + n + 1;
        }
        memcpy(p, "0.000", 5);
        memcpy(p + 1 - x, digits, (size_t)n);
        return p + 1 - x + n;
    }
    p[0] = digits[0];
    if (n > 1) {
        p[1] = '.';
        memcpy(p + 2, digits + 1, (size_t)n - 1);
        p += n + 1;
    } else {
        p += 1;
    }
    *p++ = 'e';
    int e = x;
    *p++ = e < 0 ? '-' : '+';
    if (e < 0)
        e = -e;
    if (e >= 100) {
        *p++ = (char)('0' + e / 100);
        e %= 100;
    }
    memcpy(p, MS_DIGIT_PAIRS + 2 * e, 2);
    return p + 2;
}

enum { LAYOUT_JSON, LAYOUT_REPR };

static char *w_digits(char *p, uint64_t mantissa, int exponent, int layout) {
    /* buf is longer than any digit string so that the JSON layout's fixed-size copies (vector moves) can
     * be used; the room the caller made (MS_DOUBLE_MAX) covers what they write past the text. */
    char buf[64];
    const int n = digits20(mantissa, buf);
    const char *const digits = buf + 20 - n;
    return layout == LAYOUT_JSON ? w_json_layout(p, digits, n, exponent) : w_repr_layout(p, digits, n, exponent);
}

static char *w_double(char *out, double v, int layout) {
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    const int sign = (int)(bits >> 63);
    const uint64_t mant = bits & ((1ull << DOUBLE_MANTISSA_BITS) - 1);
    const uint32_t expo = (uint32_t)((bits >> DOUBLE_MANTISSA_BITS) & 0x7FFu);
    if (expo == 0x7FFu) { /* (the repr layout's callers write NaN and infinities themselves) */
        memcpy(out, "null", 4);
        return out + 4;
    }
    char *p = out;
    if (sign)
        *p++ = '-';
    if (expo == 0 && mant == 0) {
        memcpy(p, "0.0", 3);
        return p + 3;
    }
    floating_decimal_64 fd = d2d(mant, expo);
    return w_digits(p, fd.mantissa, fd.exponent, layout);
}

static char *w_f32(char *out, float v, int layout) {
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    const uint32_t mant = bits & ((1u << FLOAT_MANTISSA_BITS) - 1);
    const uint32_t expo = (bits >> FLOAT_MANTISSA_BITS) & 0xFFu;
    if (expo == 0xFFu) {
        memcpy(out, "null", 4);
        return out + 4;
    }
    char *p = out;
    if (bits >> 31)
        *p++ = '-';
    if (expo == 0 && mant == 0) {
        memcpy(p, "0.0", 3);
        return p + 3;
    }
    floating_decimal_32 fd = f2d(mant, expo);
    return w_digits(p, fd.mantissa, fd.exponent, layout);
}

char *ms_w_double(char *out, double v) { return w_double(out, v, LAYOUT_JSON); }
char *ms_w_f32(char *out, float v) { return w_f32(out, v, LAYOUT_JSON); }
char *ms_w_double_repr(char *out, double v) { return w_double(out, v, LAYOUT_REPR); }
char *ms_w_f32_repr(char *out, float v) { return w_f32(out, v, LAYOUT_REPR); }

int ms_fmt_double(double v, char *out) { return (int)(ms_w_double(out, v) - out); }

void ms_put_u64(ms_buf *b, uint64_t v) {
    char *p = ms_buf_room(b, MS_U64_MAX);
    if (p != NULL)
        b->len += (size_t)(ms_w_u64(p, v) - p);
}

void ms_put_double(ms_buf *b, double v) {
    char *p = ms_buf_room(b, MS_DOUBLE_MAX);
    if (p != NULL)
        b->len += (size_t)(ms_w_double(p, v) - p);
}

/* Length of the valid UTF-8 sequence at s[0..n) (n >= 1, s[0] >= 0x80), or 0 when it is not one.
 * Python's strict decoder: no overlong forms, no surrogates, nothing above U+10FFFF. */
static size_t utf8_seq(const uint8_t *s, size_t n) {
    const uint8_t c = s[0];
    if (c >= 0xC2 && c <= 0xDF)
        return (n >= 2 && (s[1] & 0xC0) == 0x80) ? 2 : 0;
    if (c >= 0xE0 && c <= 0xEF) {
        if (n < 3)
            return 0;
        uint8_t lo = 0x80, hi = 0xBF;
        if (c == 0xE0)
            lo = 0xA0;
        else if (c == 0xED)
            hi = 0x9F;
        return (s[1] >= lo && s[1] <= hi && (s[2] & 0xC0) == 0x80) ? 3 : 0;
    }
    if (c >= 0xF0 && c <= 0xF4) {
        if (n < 4)
            return 0;
        uint8_t lo = 0x80, hi = 0xBF;
        if (c == 0xF0)
            lo = 0x90;
        else if (c == 0xF4)
            hi = 0x8F;
        return (s[1] >= lo && s[1] <= hi && (s[2] & 0xC0) == 0x80 && (s[3] & 0xC0) == 0x80) ? 4 : 0;
    }
    return 0;
}

static const char HEX[16] = {'0', '1', '2', '3', '4', '5', '6', '7', '8', '9', 'a', 'b', 'c', 'd', 'e', 'f'};

void ms_put_text(ms_buf *b, const uint8_t *s, size_t n) {
    if (n > (SIZE_MAX - 2) / 6) {
        b->failed = 1;
        return;
    }
    char *p = ms_buf_room(b, ms_text_max(n));
    if (p != NULL)
        b->len += (size_t)(ms_w_text(p, s, n) - p);
}

char *ms_w_text(char *p, const uint8_t *s, size_t n) {
    *p++ = '"';
    size_t i = 0;
    while (i < n) {
        const uint8_t c = s[i];
        if (c >= 0x80) {
            size_t k = utf8_seq(s + i, n - i);
            if (k) {
                memcpy(p, s + i, k);
                p += k;
                i += k;
            } else { /* backslashreplace gives the 4 characters \xNN; JSON escapes the backslash */
                p[0] = '\\';
                p[1] = '\\';
                p[2] = 'x';
                p[3] = HEX[c >> 4];
                p[4] = HEX[c & 15];
                p += 5;
                i += 1;
            }
            continue;
        }
        i += 1;
        if (c >= 0x20 && c != '"' && c != '\\') {
            *p++ = (char)c;
            continue;
        }
        *p++ = '\\';
        switch (c) {
        case '"': *p++ = '"'; break;
        case '\\': *p++ = '\\'; break;
        case '\b': *p++ = 'b'; break;
        case '\t': *p++ = 't'; break;
        case '\n': *p++ = 'n'; break;
        case '\f': *p++ = 'f'; break;
        case '\r': *p++ = 'r'; break;
        default:
            p[0] = 'u';
            p[1] = '0';
            p[2] = '0';
            p[3] = HEX[c >> 4];
            p[4] = HEX[c & 15];
            p += 5;
        }
    }
    *p++ = '"';
    return p;
}
