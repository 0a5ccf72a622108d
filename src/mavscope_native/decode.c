#include "decode.h"

#include <string.h>

#include "capture.h"
#include "fmt.h"
#include "signing.h"

#define SIGNING_EPOCH 1420070400ull

static inline float f32_at(const uint8_t *p) {
    uint32_t u = ms_le32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static inline double f64_at(const uint8_t *p) {
    uint64_t u = ms_le64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

static inline char *w_scalar(char *p, unsigned type, const uint8_t *v) {
    switch (type) {
    case MS_T_U8: return ms_w_u32(p, v[0]);
    case MS_T_I8: return ms_w_i64(p, (int8_t)v[0]);
    case MS_T_U16: return ms_w_u32(p, ms_le16(v));
    case MS_T_I16: return ms_w_i64(p, (int16_t)ms_le16(v));
    case MS_T_U32: return ms_w_u32(p, ms_le32(v));
    case MS_T_I32: return ms_w_i64(p, (int32_t)ms_le32(v));
    case MS_T_U64: return ms_w_u64(p, ms_le64(v));
    case MS_T_I64: return ms_w_i64(p, (int64_t)ms_le64(v));
    case MS_T_F32: return ms_w_f32(p, f32_at(v)); /* the shortest text of the float32 */
    case MS_T_F64: return ms_w_double(p, f64_at(v));
    default: return MS_W_LIT(p, "null"); /* never: the table parser refuses other types */
    }
}

static const uint8_t SIZE_OF[] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8, 1};

char *ms_w_fields(char *p, const ms_message *m, const uint8_t *payload, size_t len) {
    uint8_t padded[256];
    if (len > m->length)
        len = m->length; /* never: longer payloads are Python's (length-mismatch) */
    memcpy(padded, payload, len);
    memset(padded + len, 0, (size_t)m->length - len); /* the fields lie inside the message's length */
    *p++ = '{';
    for (uint16_t i = 0; i < m->nfields; i++) {
        const ms_field *f = &m->fields[i];
        if (i)
            *p++ = ',';
        p = ms_w_padded(p, f->key, f->key_len);
        const uint8_t *v = padded + f->offset; /* offset + size <= length <= 255: checked by the parser */
        const unsigned type = f->type & 0x7F;
        if (type == MS_T_CHAR) {
            p = ms_w_text(p, v, ms_char_len(v, f->count)); /* the string ends at its first NUL */
        } else if (f->type & MS_T_ARRAY) {
            *p++ = '[';
            const unsigned step = SIZE_OF[type];
            for (unsigned k = 0; k < f->count; k++) {
                if (k)
                    *p++ = ',';
                p = w_scalar(p, type, v + k * step);
            }
            *p++ = ']';
        } else {
            p = w_scalar(p, type, v);
        }
    }
    *p++ = '}';
    return p;
}

/* days since 1970-01-01 -> civil date (H. Hinnant's algorithm), for days >= 0 */
static void civil_from_days(uint64_t z, unsigned *y, unsigned *m, unsigned *d) {
    z += 719468;
    const uint64_t era = z / 146097;
    const unsigned doe = (unsigned)(z - era * 146097);
    const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
    const uint64_t yy = (uint64_t)yoe + era * 400;
    const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    const unsigned mp = (5 * doy + 2) / 153;
    *d = doy - (153 * mp + 2) / 5 + 1;
    *m = mp < 10 ? mp + 3 : mp - 9;
    *y = (unsigned)(yy + (*m <= 2));
}

static void two(char *p, unsigned v) {
    p[0] = (char)('0' + v / 10);
    p[1] = (char)('0' + v % 10);
}

void ms_iso_second(uint64_t seconds, char out[19]) {
    uint64_t t = SIGNING_EPOCH + seconds; /* seconds < 2**48 / 100000: years below 2200 */
    unsigned y, mo, d;
    civil_from_days(t / 86400, &y, &mo, &d);
    unsigned s = (unsigned)(t % 86400);
    out[0] = (char)('0' + (y / 1000) % 10);
    out[1] = (char)('0' + (y / 100) % 10);
    out[2] = (char)('0' + (y / 10) % 10);
    out[3] = (char)('0' + y % 10);
    out[4] = '-';
    two(out + 5, mo);
    out[7] = '-';
    two(out + 8, d);
    out[10] = 'T';
    two(out + 11, s / 3600);
    out[13] = ':';
    two(out + 14, (s / 60) % 60);
    out[16] = ':';
    two(out + 17, s % 60);
}

static const char HEXDIGITS[] = "0123456789abcdef";

/* The signature object up to its value: {"link_id":..,"timestamp":..,"time":"..","value":"..." */
static char *signature_head(char *p, const uint8_t *block) {
    uint64_t ts = 0;
    for (int i = 5; i >= 0; i--)
        ts = (ts << 8) | block[1 + i];
    p = MS_W_LIT(p, "{\"link_id\":");
    p = ms_w_u32(p, block[0]);
    p = MS_W_LIT(p, ",\"timestamp\":");
    p = ms_w_u64(p, ts);
    p = MS_W_LIT(p, ",\"time\":\"");
    ms_iso_second(ts / 100000, p);
    p += 19;
    unsigned f = (unsigned)(ts % 100000);
    *p = '.';
    for (int i = 5; i >= 1; i--) {
        p[i] = (char)('0' + f % 10);
        f /= 10;
    }
    p[6] = 'Z';
    p += 7;
    p = MS_W_LIT(p, "\",\"value\":\"");
    for (int i = 0; i < 6; i++) {
        *p++ = HEXDIGITS[block[7 + i] >> 4];
        *p++ = HEXDIGITS[block[7 + i] & 15];
    }
    return p;
}

char *ms_w_signature_nokey(char *p, const uint8_t *block) {
    return MS_W_LIT(signature_head(p, block), "\",\"status\":\"no-key\"}");
}

_Static_assert(MS_SIGNATURE_VALID_EXTRA >= 64 + MS_SIGN_NAME_MAX + MS_DOUBLE_MAX, "room of a valid signature");

char *ms_w_signature_valid(char *p, const uint8_t *block, const char *key, size_t key_len, int has_time, double t) {
    p = MS_W_LIT(signature_head(p, block), "\",\"status\":\"valid\",\"key\":");
    memcpy(p, key, key_len);
    p += key_len;
    if (has_time) {
        uint64_t ts = 0;
        for (int i = 5; i >= 0; i--)
            ts = (ts << 8) | block[1 + i];
        /* Signature.unix_time - frame.time, as Python computes them: SIGNING_EPOCH + ts / 100_000 */
        const double unix_time = (double)SIGNING_EPOCH + (double)ts / 100000.0;
        p = MS_W_LIT(p, ",\"skew\":");
        p = ms_w_double(p, ms_round6(unix_time - t));
    }
    *p++ = '}';
    return p;
}
