#include "summary.h"

#include "blob.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "fmt.h"
#include "mavlink.h"

#define MAX_ENTRIES (1u << 20)

static const char HEX[] = "0123456789abcdef";

/* n bytes of text (no newline in it), or NULL (and `bad`) */
static const char *take_text(ms_cursor *c, size_t n) {
    if (c->bad || (size_t)(c->end - c->p) < n || memchr(c->p, '\n', n) != NULL) {
        c->bad = 1;
        return NULL;
    }
    const char *s = (const char *)c->p;
    c->p += n;
    return s;
}

static int is_signed_type(unsigned type) {
    return type == MS_T_I8 || type == MS_T_I16 || type == MS_T_I32 || type == MS_T_I64;
}

/* n entries, strictly sorted (signed or unsigned); their longest name in *longest. 0, or -1 when bad. */
static int take_entries(ms_cursor *c, ms_enum_entry **out, uint64_t n, int sgn, size_t *longest) {
    if (n > MAX_ENTRIES)
        return -1;
    ms_enum_entry *v = calloc(n ? n : 1, sizeof *v);
    *out = v;
    if (v == NULL)
        return -1;
    for (uint64_t e = 0; e < n; e++) {
        v[e].value = ms_take(c, 8);
        v[e].name_len = (uint8_t)ms_take(c, 1);
        v[e].name = take_text(c, v[e].name_len);
        if (c->bad)
            return -1;
        if (e && (sgn ? (int64_t)v[e].value <= (int64_t)v[e - 1].value : v[e].value <= v[e - 1].value))
            return -1; /* not strictly sorted: the lookup would miss */
        if (v[e].name_len > *longest)
            *longest = v[e].name_len;
    }
    return 0;
}

void ms_summary_free(ms_summary *s) {
    if (s->messages != NULL) {
        for (size_t i = 0; i < s->count; i++) {
            ms_smessage *m = &s->messages[i];
            if (m->items != NULL)
                for (size_t k = 0; k < m->nitems; k++)
                    free(m->items[k].entries);
            free(m->items);
            if (m->commands != NULL)
                for (size_t k = 0; k < m->ncommands; k++)
                    free(m->commands[k].entries);
            free(m->commands);
        }
    }
    free(s->messages);
    free(s->blob);
    memset(s, 0, sizeof *s);
}

int ms_summary_parse(ms_summary *s, const ms_table *t, const uint8_t *blob, size_t len) {
    memset(s, 0, sizeof *s);
    s->table = t;
    if (len < 12 || memcmp(blob, "MSSM", 4) != 0)
        return -1;
    s->blob = malloc(len);
    if (s->blob == NULL)
        return -1;
    memcpy(s->blob, blob, len);
    ms_cursor c = {s->blob + 4, s->blob + len, 0};
    if (ms_take(&c, 4) != 3 || ms_take(&c, 4) != t->count)
        goto fail;
    s->messages = calloc(t->count ? t->count : 1, sizeof *s->messages);
    if (s->messages == NULL)
        goto fail;
    s->count = t->count;
    for (size_t i = 0; i < t->count; i++) {
        const ms_message *tm = &t->messages[i];
        ms_smessage *m = &s->messages[i];
        if (ms_take(&c, 4) != tm->msgid)
            goto fail;
        const uint64_t flags = ms_take(&c, 1);
        m->python_only = (uint8_t)(flags & 1);
        m->nitems = (uint8_t)ms_take(&c, 1);
        m->name_len = (uint16_t)ms_take(&c, 2);
        m->name = take_text(&c, m->name_len);
        if (c.bad)
            goto fail;
        m->python_if = MS_NO_FIELD;
        if (flags & 2) { /* a scalar integer field of the message */
            m->python_if = (uint16_t)ms_take(&c, 2);
            if (c.bad || m->python_if >= tm->nfields || tm->fields[m->python_if].type < MS_T_U8 ||
                tm->fields[m->python_if].type > MS_T_I32) /* (MS_T_ARRAY is above: no list) */
                goto fail;
        }
        m->param1 = (uint16_t)ms_take(&c, 2);
        m->command = (uint16_t)ms_take(&c, 2);
        uint64_t ncommands = ms_take(&c, 4);
        if (c.bad || ncommands > MAX_ENTRIES)
            goto fail;
        if (m->command != MS_NO_FIELD) { /* a scalar integer of at most 32 bits: int_at is exact */
            if (m->command >= tm->nfields || tm->fields[m->command].type < MS_T_U8 ||
                tm->fields[m->command].type > MS_T_I32)
                goto fail;
        } else if (ncommands || m->param1 != MS_NO_FIELD) {
            goto fail;
        }
        if (m->param1 != MS_NO_FIELD && (m->param1 >= tm->nfields || tm->fields[m->param1].type != MS_T_F32))
            goto fail;
        m->commands = calloc(ncommands ? ncommands : 1, sizeof *m->commands);
        if (m->commands == NULL)
            goto fail;
        m->ncommands = (uint32_t)ncommands;
        size_t longest = 0;
        for (uint32_t k = 0; k < ncommands; k++) {
            ms_command *cmd = &m->commands[k];
            cmd->value = (int64_t)ms_take(&c, 8);
            cmd->flags = (uint8_t)(ms_take(&c, 1) & (MS_CMD_PYTHON | MS_CMD_BITS));
            cmd->labelled = (uint8_t)(ms_take(&c, 1) & 0x7F);
            uint64_t n = ms_take(&c, 4);
            if (c.bad || (k && cmd->value <= m->commands[k - 1].value))
                goto fail;
            cmd->nentries = (uint32_t)n;
            size_t one = 0;
            if (take_entries(&c, &cmd->entries, n, 1, &one) != 0)
                goto fail;
            if (cmd->flags & MS_CMD_BITS) { /* every name, " | " between, and the rest in hex */
                one = 2 + 16;
                for (uint32_t e = 0; e < n; e++) {
                    if ((int64_t)cmd->entries[e].value < 0)
                        goto fail; /* flags are non-negative */
                    one += 3 + (size_t)cmd->entries[e].name_len;
                }
            }
            if (one > longest)
                longest = one;
        }
        m->items = calloc(m->nitems ? m->nitems : 1, sizeof *m->items);
        if (m->items == NULL)
            goto fail;
        m->info_max = (size_t)m->name_len + 32 + longest; /* " [signed link 255]", a named param1 */
        for (size_t k = 0; k < m->nitems; k++) {
            ms_sitem *it = &m->items[k];
            it->field = (uint16_t)ms_take(&c, 2);
            it->how = (uint8_t)ms_take(&c, 1);
            it->param = (uint8_t)ms_take(&c, 1);
            it->label_len = (uint8_t)ms_take(&c, 1);
            it->label = take_text(&c, it->label_len);
            uint64_t n = ms_take(&c, 4);
            if (c.bad || it->field >= tm->nfields || it->how > MS_HOW_DEGREES || n > MAX_ENTRIES || it->param > 7)
                goto fail;
            const ms_field *f = &tm->fields[it->field];
            const unsigned type = f->type & 0x7F;
            if (it->param && (m->command == MS_NO_FIELD || (f->type & MS_T_ARRAY) || type < MS_T_U8 ||
                              type > MS_T_F64))
                goto fail; /* a command parameter is a number of a command message */
            it->nentries = (uint32_t)n;
            size_t value_max = MS_DEG_MAX > MS_REPR_MAX ? MS_DEG_MAX : MS_REPR_MAX; /* also any integer */
            if (take_entries(&c, &it->entries, n, is_signed_type(type), &value_max) != 0)
                goto fail;
            if (type == MS_T_CHAR)
                value_max = 4 * (size_t)f->count + 2;
            m->info_max += 1 + (size_t)it->label_len + value_max;
        }
    }
    if (c.p != c.end)
        goto fail;
    return 0;
fail:
    ms_summary_free(s);
    return -1;
}

/* ---- numbers and strings as Python formats them ------------------------------------------------ */

static char *copy_printf(char *p, const char *fmt, double v) {
    char tmp[400];
    int n = snprintf(tmp, sizeof tmp, fmt, v);
    if (n < 0 || (size_t)n >= sizeof tmp)
        n = 0; /* never: callers bound v so the text fits */
    memcpy(p, tmp, (size_t)n);
    return p + n;
}

/* A float or double field's value as fields/summary.py `_short` writes it (mavlink/floats.py): the
 * shortest text that reads back as the same float32, or repr of a double; NaN as semantics.NAN_TEXT */
static char *w_float(char *p, unsigned type, const uint8_t *v) {
    double d;
    float f = 0;
    if (type == MS_T_F32) {
        uint32_t u = ms_le32(v);
        memcpy(&f, &u, sizeof f);
        d = f;
    } else {
        uint64_t u = ms_le64(v);
        memcpy(&d, &u, sizeof d);
    }
    if (d != d)
        return MS_W_LIT(p, "NaN");
    if (isinf(d))
        return d < 0 ? MS_W_LIT(p, "-inf") : MS_W_LIT(p, "inf");
    return type == MS_T_F32 ? ms_w_f32_repr(p, f) : ms_w_double_repr(p, d);
}

/* n / 10**digits with exactly `digits` decimals (digits <= 9) */
static char *w_fixed(char *p, uint64_t n, int digits) {
    uint32_t scale = 1;
    for (int i = 0; i < digits; i++)
        scale *= 10;
    p = ms_w_u64(p, n / scale);
    *p++ = '.';
    uint32_t frac = (uint32_t)(n % scale);
    for (int i = digits - 1; i >= 0; i--) {
        p[i] = (char)('0' + frac % 10);
        frac /= 10;
    }
    return p + digits;
}

char *ms_w_degrees(char *p, int64_t v, int is_unsigned) {
    const uint64_t u = (uint64_t)v;
    const int neg = !is_unsigned && v < 0;
    const uint64_t mag = neg ? (uint64_t)(-(v + 1)) + 1u : u;
    if (mag >= (1ull << 40)) {
        /* v / 1e7 in double (Python converts the int correctly rounded, as C does), then %.7f */
        double q = (is_unsigned ? (double)u : (double)v) / 1e7;
        return copy_printf(p, "%.7f", q);
    }
    /* |v| < 2**40: the double nearest v / 1e7 is within 1e-11 of it, so its 7 decimals are v's digits */
    if (neg)
        *p++ = '-';
    return w_fixed(p, mag, 7);
}

char *ms_w_reltime(char *p, double t) {
    if (!(fabs(t) < 1e15))
        return NULL; /* NaN, infinite or a huge span: the Python path writes those */
    char body[40];
    char *q = body;
    const int neg = signbit(t) != 0;
    double a = fabs(t);
    int fast = 0;
    if (a < 1e7) {
        double scaled = a * 1e6; /* < 1e13: one rounding, error below 0.001 */
        double fl = floor(scaled);
        double frac = scaled - fl;
        if (fabs(frac - 0.5) > 0.002) {
            if (neg)
                *q++ = '-';
            q = w_fixed(q, (uint64_t)fl + (frac > 0.5), 6);
            fast = 1;
        }
    }
    if (!fast)
        q = copy_printf(body, "%.6f", t); /* glibc: exact, ties to even, as Python */
    size_t n = (size_t)(q - body);
    for (size_t i = n; i < 11; i++)
        *p++ = ' ';
    memcpy(p, body, n);
    return p + n;
}


char *ms_w_repr_ascii(char *p, const uint8_t *s, size_t n) {
    n = ms_char_len(s, n); /* a string ends at its first NUL (char_text) */
    int sq = 0, dq = 0;
    for (size_t i = 0; i < n; i++) {
        if (s[i] >= 0x80)
            return NULL;
        sq |= s[i] == '\'';
        dq |= s[i] == '"';
    }
    const char quote = sq && !dq ? '"' : '\'';
    *p++ = quote;
    for (size_t i = 0; i < n; i++) {
        const uint8_t ch = s[i];
        if (ch == (uint8_t)quote || ch == '\\') {
            *p++ = '\\';
            *p++ = (char)ch;
        } else if (ch == '\t') {
            p = MS_W_LIT(p, "\\t");
        } else if (ch == '\n') {
            p = MS_W_LIT(p, "\\n");
        } else if (ch == '\r') {
            p = MS_W_LIT(p, "\\r");
        } else if (ch < 0x20 || ch == 0x7F) {
            *p++ = '\\';
            *p++ = 'x';
            *p++ = HEX[ch >> 4];
            *p++ = HEX[ch & 15];
        } else {
            *p++ = (char)ch;
        }
    }
    *p++ = quote;
    return p;
}

/* ---- the lines ---------------------------------------------------------------------------------- */

static char *pad_left(char *p, const char *text, size_t n, size_t width) {
    for (size_t i = n; i < width; i++)
        *p++ = ' ';
    memcpy(p, text, n);
    return p + n;
}

size_t ms_summary_prefix(char *out, int has_time, double t, int has_t0, double t0, const char *src, size_t src_len,
                         const char *dst, size_t dst_len) {
    char *p = out;
    *p++ = ' ';
    if (has_time && has_t0) {
        p = ms_w_reltime(p, t - t0);
        if (p == NULL)
            return 0;
    } else {
        p = MS_W_LIT(p, "          -");
    }
    *p++ = ' ';
    size_t chars;
    if (src != NULL) { /* f"{src} → {dst}": both ASCII, the arrow one character of three bytes */
        memcpy(p, src, src_len);
        p += src_len;
        p = MS_W_LIT(p, " \xe2\x86\x92 ");
        memcpy(p, dst, dst_len);
        p += dst_len;
        chars = src_len + 3 + dst_len;
    } else {
        p = MS_W_LIT(p, "tlog");
        chars = 4;
    }
    for (; chars < 34; chars++)
        *p++ = ' ';
    *p++ = ' ';
    return (size_t)(p - out);
}

static inline int64_t int_at(unsigned type, const uint8_t *v) {
    switch (type) {
    case MS_T_U8: return v[0];
    case MS_T_I8: return (int8_t)v[0];
    case MS_T_U16: return ms_le16(v);
    case MS_T_I16: return (int16_t)ms_le16(v);
    case MS_T_U32: return ms_le32(v);
    case MS_T_I32: return (int32_t)ms_le32(v);
    default: return (int64_t)ms_le64(v); /* U64 (bits), I64 */
    }
}

static inline double float_at(unsigned type, const uint8_t *v) {
    if (type == MS_T_F32) {
        uint32_t u = ms_le32(v);
        float f;
        memcpy(&f, &u, sizeof f);
        return (double)f;
    }
    uint64_t u = ms_le64(v);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

static const ms_enum_entry *lookup(const ms_enum_entry *entries, uint32_t count, int64_t value, int sgn) {
    size_t lo = 0, hi = count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        const uint64_t ev = entries[mid].value;
        int less = sgn ? (int64_t)ev < value : ev < (uint64_t)value;
        if (ev == (uint64_t)value)
            return &entries[mid];
        if (less)
            lo = mid + 1;
        else
            hi = mid;
    }
    return NULL;
}

/* The value of one item, as fields/summary.py _short writes it; NULL: Python must write it. */
static char *w_item(char *p, const ms_sitem *it, const ms_field *f, const uint8_t *padded) {
    const unsigned type = f->type & 0x7F;
    const uint8_t *v = padded + f->offset;
    if (type == MS_T_CHAR)
        return ms_w_repr_ascii(p, v, f->count);
    if (f->type & MS_T_ARRAY) {
        *p++ = '[';
        p = ms_w_u32(p, f->count);
        *p++ = ']';
        return p;
    }
    if (type == MS_T_F32 || type == MS_T_F64)
        return w_float(p, type, v);
    const int64_t x = int_at(type, v);
    const int sgn = is_signed_type(type);
    if (it->how == MS_HOW_ENUM) {
        const ms_enum_entry *e = lookup(it->entries, it->nentries, x, sgn);
        if (e != NULL && e->name_len) {
            memcpy(p, e->name, e->name_len);
            return p + e->name_len;
        }
    } else if (it->how == MS_HOW_DEGREES) {
        return ms_w_degrees(p, x, !sgn);
    }
    return sgn ? ms_w_i64(p, x) : ms_w_u64(p, (uint64_t)x);
}

enum { NAMED = 1, UNNAMED = 0, PYTHON = -1 };

/* The entry of the command a command message carries (its MAV_CMD value), or NULL: none in the table */
static const ms_command *find_command(const ms_smessage *sm, const ms_message *m, const uint8_t *padded) {
    const ms_field *cf = &m->fields[sm->command];
    const int64_t command = int_at(cf->type & 0x7F, padded + cf->offset);
    size_t lo = 0, hi = sm->ncommands;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        const ms_command *c = &sm->commands[mid];
        if (c->value == command)
            return c;
        if (c->value < command)
            lo = mid + 1;
        else
            hi = mid;
    }
    return NULL;
}

/* semantics.command_param_name(dialect, command, 1, param1) for a command message's param1, `c` its
 * command's entry (or NULL): NAMED (*n the whole value: an entry's name, or with MS_CMD_BITS the names of
 * its bits), UNNAMED (the value is shown), or PYTHON (an infinite param1, on which Python raises; a
 * negative value for bits) */
static int param1_name(const ms_smessage *sm, const ms_message *m, const uint8_t *padded, const ms_command *c,
                       int64_t *n) {
    const double v = float_at(MS_T_F32, padded + m->fields[sm->param1].offset);
    if (isinf(v))
        return PYTHON;
    if (v != v || v != trunc(v))
        return UNNAMED; /* NaN, not whole */
    if (c == NULL)
        return UNNAMED;
    const int in_range = fabs(v) < 9.2e18; /* else no entry's value; Python's flags_of shows it in hex */
    if (c->flags & MS_CMD_PYTHON)
        return PYTHON;
    if (c->flags & MS_CMD_BITS) /* flags_of(0) is empty: None; negative or huge values: Python */
        return !in_range || v < 0 ? PYTHON : v > 0 ? (*n = (int64_t)v, NAMED) : UNNAMED;
    if (!in_range)
        return UNNAMED;
    *n = (int64_t)v;
    return lookup(c->entries, c->nentries, *n, 1) != NULL ? NAMED : UNNAMED;
}

/* semantics.holds_nothing: a number field that holds 0 (or -0.0) or NaN */
static int holds_nothing(const ms_field *f, const uint8_t *padded) {
    const unsigned type = f->type & 0x7F;
    if (type == MS_T_F32 || type == MS_T_F64) {
        const double d = float_at(type, padded + f->offset);
        return d == 0 || d != d;
    }
    return int_at(type, padded + f->offset) == 0;
}

/* Dialect enum flags_of(n) joined by " | ": the names of the entries whose bits n holds, the rest in hex */
static char *w_flags(char *p, const ms_command *cmd, uint64_t n) {
    uint64_t rest = n;
    const char *sep = "";
    for (uint32_t i = 0; i < cmd->nentries; i++) {
        const uint64_t bits = cmd->entries[i].value;
        if (bits && (n & bits) == bits) {
            memcpy(p, sep, strlen(sep));
            p += strlen(sep);
            memcpy(p, cmd->entries[i].name, cmd->entries[i].name_len);
            p += cmd->entries[i].name_len;
            rest &= ~bits;
            sep = " | ";
        }
    }
    if (rest) {
        char hex[17];
        int k = 16;
        while (rest) {
            hex[--k] = HEX[rest & 15];
            rest >>= 4;
        }
        memcpy(p, sep, strlen(sep));
        p += strlen(sep);
        p = MS_W_LIT(p, "0x");
        memcpy(p, hex + k, (size_t)(16 - k));
        p += 16 - k;
    }
    return p;
}

#define LINE_HEAD_MAX 96 /* "12.3" (up to 41 bytes), "255/255 v2 seq 255 " and the newline */

int ms_write_summary(const ms_summary *s, ms_buf *out, uint64_t number, const char *prefix, size_t prefix_len,
                     const uint8_t *d, const uint32_t *frames, const uint8_t *bad, size_t count) {
    char num[2 * MS_U64_MAX + 2];
    const size_t num_len = (size_t)(ms_w_u64(num, number) - num);
    for (size_t i = 0; i < count; i++) {
        const uint8_t *f = d + frames[2 * i];
        const size_t size = frames[2 * i + 1];
        const int v2 = f[0] == MS_STX_V2;
        const size_t hlen = v2 ? MS_HEADER_V2 : MS_HEADER_V1;
        size_t len = f[1];
        const uint32_t msgid = v2 ? (uint32_t)f[7] | ((uint32_t)f[8] << 8) | ((uint32_t)f[9] << 16) : f[5];
        const ms_message *m = ms_table_get(s->table, msgid); /* found by the walk's scan */
        if (m == NULL)
            return 1;
        const ms_smessage *sm = ms_summary_get(s, m);
        if (sm->python_only)
            return 1;
        const size_t room = prefix_len + LINE_HEAD_MAX + sm->info_max + 16; /* + " [CRC bad]" */
        char *const start = ms_buf_room(out, room);
        if (start == NULL)
            return -1;
        char *p = start;
        size_t n = num_len; /* frame_number(): "12", then "12.2", "12.3" for the frames after the first */
        if (i) {
            num[num_len] = '.';
            n = (size_t)(ms_w_u64(num + num_len + 1, i + 1) - num);
        }
        p = pad_left(p, num, n, 7);
        memcpy(p, prefix, prefix_len);
        p += prefix_len;
        char num[4];
        const uint8_t sysid = f[v2 ? 5 : 3], compid = f[v2 ? 6 : 4], seq = f[v2 ? 4 : 2];
        p = pad_left(p, num, (size_t)(ms_w_u8(num, sysid) - num), 3);
        *p++ = '/';
        char *c = ms_w_u8(p, compid);
        while (c < p + 3)
            *c++ = ' ';
        p = MS_W_LIT(c, " v");
        *p++ = v2 ? '2' : '1';
        p = MS_W_LIT(p, " seq ");
        p = pad_left(p, num, (size_t)(ms_w_u8(num, seq) - num), 3);
        *p++ = ' ';
        memcpy(p, sm->name, sm->name_len);
        p += sm->name_len;
        uint8_t padded[256];
        if (len > m->length)
            len = m->length; /* never: the scan hands longer payloads back */
        memcpy(padded, f + hlen, len);
        memset(padded + len, 0, (size_t)m->length - len);
        if (sm->python_if != MS_NO_FIELD) {
            const ms_field *pf = &m->fields[sm->python_if];
            if (int_at(pf->type, padded + pf->offset) != 0)
                return 1; /* STATUSTEXT's chunk of a long text: "[chunk N of id M]" is Python's */
        }
        const ms_command *cmd = sm->command != MS_NO_FIELD ? find_command(sm, m, padded) : NULL;
        const unsigned labelled = cmd != NULL ? cmd->labelled : 0;
        int64_t whole = 0;
        int named = UNNAMED;
        if (sm->param1 != MS_NO_FIELD) {
            named = param1_name(sm, m, padded, cmd, &whole);
            if (named == PYTHON)
                return 1;
        }
        for (size_t k = 0; k < sm->nitems; k++) {
            const ms_sitem *it = &sm->items[k];
            if (it->param && !(labelled >> (it->param - 1) & 1) && holds_nothing(&m->fields[it->field], padded))
                continue; /* semantics.param_shown: unlabelled, holding nothing */
            *p++ = ' ';
            memcpy(p, it->label, it->label_len);
            p += it->label_len;
            if (named == NAMED && it->field == sm->param1) {
                if (cmd->flags & MS_CMD_BITS) {
                    p = w_flags(p, cmd, (uint64_t)whole);
                } else {
                    const ms_enum_entry *e = lookup(cmd->entries, cmd->nentries, whole, 1);
                    memcpy(p, e->name, e->name_len);
                    p += e->name_len;
                }
                continue;
            }
            p = w_item(p, it, &m->fields[it->field], padded);
            if (p == NULL)
                return 1;
        }
        if (bad[i])
            p = MS_W_LIT(p, " [CRC bad]"); /* summary_info: a CRC verdict that is not ok */
        if (v2 && (f[2] & 1)) {
            p = MS_W_LIT(p, " [signed link ");
            p = ms_w_u8(p, f[size - MS_SIGNATURE_LEN]);
            *p++ = ']';
        }
        *p++ = '\n';
        if ((size_t)(p - start) > room)
            abort(); /* the bound above is wrong: memory is already corrupt, stop here */
        out->len += (size_t)(p - start);
    }
    return 0;
}
