/* Common parts of the record walkers: notes, the dispatch by format, raw streams, times. */
#include "capture.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RAW_CHUNK 65536 /* capture/raw.py CHUNK */

const char *ms_note_code_name(int code) {
    switch (code) {
    case MS_NOTE_RECORD_TRUNCATED: return "record-truncated";
    case MS_NOTE_RECORD_SNAPPED: return "record-snapped";
    case MS_NOTE_CAPTURE_GARBAGE: return "capture-garbage";
    default: return "capture-garbage";
    }
}

void ms_notes_init(ms_notes *ns) {
    ns->v = NULL;
    ns->n = 0;
    ns->cap = 0;
    ns->failed = 0;
    ms_buf_init(&ns->text);
}

void ms_notes_free(ms_notes *ns) {
    free(ns->v);
    ms_buf_free(&ns->text);
    ms_notes_init(ns);
}

void ms_notes_clear(ms_notes *ns) {
    ns->n = 0;
    ns->text.len = 0;
}

void ms_notes_add(ms_notes *ns, int code, int64_t offset, const char *fmt, ...) {
    if (ns->n == ns->cap) {
        size_t cap = ns->cap ? 2 * ns->cap : 4;
        ms_note *v = realloc(ns->v, cap * sizeof *v);
        if (v == NULL) {
            ns->failed = 1;
            return;
        }
        ns->v = v;
        ns->cap = cap;
    }
    char tmp[512];
    va_list ap;
    va_start(ap, fmt);
    int len = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (len < 0 || (size_t)len >= sizeof tmp) { /* every message is far shorter */
        ns->failed = 1;
        return;
    }
    size_t at = ns->text.len;
    ms_buf_put(&ns->text, tmp, (size_t)len);
    if (ns->text.failed) {
        ns->failed = 1;
        return;
    }
    ms_note *note = &ns->v[ns->n++];
    note->code = code;
    note->offset = offset;
    note->msg_off = at;
    note->msg_len = (size_t)len;
}

/* Append every note of `src` to `dst`. */
static void notes_extend(ms_notes *dst, const ms_notes *src) {
    for (size_t i = 0; i < src->n; i++) {
        const ms_note *s = &src->v[i];
        ms_notes_add(dst, s->code, s->offset, "%.*s", (int)s->msg_len, src->text.data + s->msg_off);
    }
}

void ms_reader_emit(ms_reader *r, ms_record *rec) {
    /* swap: the pending notes become the record's, the old record notes are recycled */
    ms_notes tmp = r->out;
    r->out = r->pending;
    r->pending = tmp;
    ms_notes_clear(&r->pending);
    rec->notes = &r->out;
    r->n = rec->number;
}

void ms_reader_init(ms_reader *r, const uint8_t *buf, size_t size, int kind) {
    memset(r, 0, sizeof *r);
    r->buf = buf;
    r->size = size;
    r->kind = kind;
    r->last_sec = -1;
    r->last_ts = -1;
    ms_notes_init(&r->pending);
    ms_notes_init(&r->out);
    if (kind == MS_KIND_PCAP)
        ms_pcap_init(r);
    else if (kind == MS_KIND_PCAPNG)
        ms_pcapng_init(r);
}

void ms_reader_free(ms_reader *r) {
    ms_notes_free(&r->pending);
    ms_notes_free(&r->out);
    free(r->ifaces);
    r->ifaces = NULL;
    r->nifaces = r->capifaces = 0;
}

static int raw_next(ms_reader *r, ms_record *rec) {
    if (r->pos >= r->size)
        return 0;
    size_t len = r->size - r->pos < RAW_CHUNK ? r->size - r->pos : RAW_CHUNK;
    memset(rec, 0, sizeof *rec);
    rec->number = r->n + 1;
    rec->time_kind = MS_TIME_NONE;
    rec->linktype = MS_LINKTYPE_RAW;
    rec->start = r->pos;
    rec->len = len;
    rec->orig_len = len;
    ms_reader_emit(r, rec);
    r->pos += len;
    return 1;
}

int ms_reader_next(ms_reader *r, ms_record *rec) {
    if (r->done)
        return 0;
    int got;
    ms_notes_clear(&r->out);
    switch (r->kind) {
    case MS_KIND_PCAP: got = ms_pcap_next(r, rec); break;
    case MS_KIND_PCAPNG: got = ms_pcapng_next(r, rec); break;
    case MS_KIND_TLOG: got = ms_tlog_next(r, rec); break;
    case MS_KIND_RAW: got = raw_next(r, rec); break;
    default: got = 0;
    }
    if (r->pending.failed || r->out.failed)
        return -1;
    if (got <= 0)
        r->done = 1;
    return got;
}

/* Python's notes_a + notes_b for records built from a packet block (see capture_pcapng.c) */
void ms_notes_extend(ms_notes *dst, const ms_notes *src);
void ms_notes_extend(ms_notes *dst, const ms_notes *src) { notes_extend(dst, src); }

#if defined(__SIZEOF_INT128__)
__extension__ typedef unsigned __int128 ms_u128;

static int bitlen128(ms_u128 v) {
    uint64_t hi = (uint64_t)(v >> 64);
    if (hi)
        return 128 - __builtin_clzll(hi);
    uint64_t lo = (uint64_t)v;
    return lo ? 64 - __builtin_clzll(lo) : 0;
}

double ms_div_u64(uint64_t num, uint64_t den) {
    if (num == 0)
        return 0.0;
    if (num <= (1ull << 53) && den <= (1ull << 53)) /* both exact: one IEEE division rounds correctly */
        return (double)num / (double)den;
    const int nb = 64 - __builtin_clzll(num);
    const int db = 64 - __builtin_clzll(den);
    int s = 55 + db - nb; /* shift so that the quotient has at least 55 bits */
    if (s < 0)
        s = 0;
    const ms_u128 big = (ms_u128)num << s; /* nb + s <= 119 */
    const ms_u128 q = big / den;
    const int sticky = (big % den) != 0;
    const int extra = bitlen128(q) - 53; /* >= 2 */
    ms_u128 mant = q >> extra;
    const ms_u128 rest = q & ((((ms_u128)1) << extra) - 1);
    const ms_u128 half = ((ms_u128)1) << (extra - 1);
    if (rest > half || (rest == half && (sticky || (mant & 1))))
        mant += 1; /* round half to even, as Python does */
    return ldexp((double)(uint64_t)mant, extra - s);
}
#define MS_HAVE_DIV 1
#else
double ms_div_u64(uint64_t num, uint64_t den) { return (double)num / (double)den; }
#define MS_HAVE_DIV 0
#endif

int ms_record_time(const ms_record *rec, double *out) {
    if (rec->time_kind == MS_TIME_NONE)
        return 0;
    if (rec->time_kind == MS_TIME_DOUBLE) {
        *out = rec->time;
        return 1;
    }
    uint64_t units = 1;
    if (rec->units_pow2) {
        if (rec->units_exp > 63)
            return -1;
        units = 1ull << rec->units_exp;
    } else {
        if (rec->units_exp > 19)
            return -1;
        for (int i = 0; i < rec->units_exp; i++)
            units *= 10u;
    }
    if (!MS_HAVE_DIV && (rec->ticks > (1ull << 53) || units > (1ull << 53)))
        return -1;
    /* Python: ticks / units (int / int, correctly rounded) + tsoffset (the int rounded to a double) */
    *out = ms_div_u64(rec->ticks, units) + (double)rec->tsoffset;
    return 1;
}
