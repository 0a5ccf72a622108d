#include "decode.h"

#include <string.h>

#include "capture.h"
#include "fmt.h"

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

static void put_scalar(ms_buf *b, unsigned type, const uint8_t *p) {
    switch (type) {
    case MS_T_U8: ms_put_u64(b, p[0]); break;
    case MS_T_I8: ms_put_i64(b, (int8_t)p[0]); break;
    case MS_T_U16: ms_put_u64(b, ms_le16(p)); break;
    case MS_T_I16: ms_put_i64(b, (int16_t)ms_le16(p)); break;
    case MS_T_U32: ms_put_u64(b, ms_le32(p)); break;
    case MS_T_I32: ms_put_i64(b, (int32_t)ms_le32(p)); break;
    case MS_T_U64: ms_put_u64(b, ms_le64(p)); break;
    case MS_T_I64: ms_put_i64(b, (int64_t)ms_le64(p)); break;
    case MS_T_F32: ms_put_double(b, (double)f32_at(p)); break;
    case MS_T_F64: ms_put_double(b, f64_at(p)); break;
    default: MS_BUF_LIT(b, "null"); break; /* never: the table parser refuses other types */
    }
}

static const size_t SIZE_OF[] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8, 1};

void ms_put_fields(ms_buf *b, const ms_message *m, const uint8_t *payload, size_t len) {
    uint8_t padded[256];
    memset(padded, 0, sizeof padded);
    if (len > sizeof padded)
        len = sizeof padded;
    memcpy(padded, payload, len);
    ms_buf_byte(b, '{');
    for (uint16_t i = 0; i < m->nfields; i++) {
        const ms_field *f = &m->fields[i];
        if (i)
            ms_buf_byte(b, ',');
        ms_buf_put(b, f->key, f->key_len);
        const uint8_t *p = padded + f->offset; /* offset + size <= length <= 255: checked by the parser */
        unsigned type = f->type & 0x7F;
        if (type == MS_T_CHAR) {
            size_t n = f->count;
            while (n && p[n - 1] == 0)
                n--;
            ms_put_text(b, p, n);
        } else if (f->type & MS_T_ARRAY) {
            ms_buf_byte(b, '[');
            for (unsigned k = 0; k < f->count; k++) {
                if (k)
                    ms_buf_byte(b, ',');
                put_scalar(b, type, p + k * SIZE_OF[type]);
            }
            ms_buf_byte(b, ']');
        } else {
            put_scalar(b, type, p);
        }
    }
    ms_buf_byte(b, '}');
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

void ms_put_signature_nokey(ms_buf *b, const uint8_t *block) {
    uint64_t ts = 0;
    for (int i = 5; i >= 0; i--)
        ts = (ts << 8) | block[1 + i];
    MS_BUF_LIT(b, "{\"link_id\":");
    ms_put_u64(b, block[0]);
    MS_BUF_LIT(b, ",\"timestamp\":");
    ms_put_u64(b, ts);
    MS_BUF_LIT(b, ",\"time\":\"");
    char iso[19];
    ms_iso_second(ts / 100000, iso);
    ms_buf_put(b, iso, sizeof iso);
    char frac[7];
    unsigned f = (unsigned)(ts % 100000);
    frac[0] = '.';
    for (int i = 5; i >= 1; i--) {
        frac[i] = (char)('0' + f % 10);
        f /= 10;
    }
    frac[6] = 'Z';
    ms_buf_put(b, frac, sizeof frac);
    MS_BUF_LIT(b, "\",\"value\":\"");
    char hex[12];
    for (int i = 0; i < 6; i++) {
        hex[2 * i] = HEXDIGITS[block[7 + i] >> 4];
        hex[2 * i + 1] = HEXDIGITS[block[7 + i] & 15];
    }
    ms_buf_put(b, hex, sizeof hex);
    MS_BUF_LIT(b, "\",\"status\":\"no-key\"}");
}
