/* Common parts of the record walkers: notes, reading windows (capture/reader.py), the dispatch by
 * format, raw streams (capture/raw.py), record times. */
#if !defined(_WIN32)
#define _POSIX_C_SOURCE 200809L /* pread */
#define _FILE_OFFSET_BITS 64
#endif
#include "capture.h"

#include <errno.h>
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
    case MS_NOTE_TIME_OUT_OF_RANGE: return "time-out-of-range";
    case MS_NOTE_TIME_CHECK: return "time-check";
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

void ms_notes_extend(ms_notes *dst, const ms_notes *src) {
    for (size_t i = 0; i < src->n; i++) {
        const ms_note *s = &src->v[i];
        ms_notes_add(dst, s->code, s->offset, "%.*s", (int)s->msg_len, src->text.data + s->msg_off);
    }
    if (src->failed)
        dst->failed = 1;
}

void ms_record_set(ms_record *rec, int64_t linktype, const uint8_t *data, size_t len, uint64_t offset,
                   uint64_t orig_len) {
    memset(rec, 0, sizeof *rec);
    rec->time_kind = MS_TIME_NONE;
    rec->linktype = linktype;
    rec->data = len ? data : (const uint8_t *)"";
    rec->len = len;
    rec->offset = offset;
    rec->orig_len = orig_len;
}

void ms_reader_emit(ms_reader *r, ms_record *rec) {
    /* swap: the pending notes become the record's, the old record notes are recycled */
    ms_notes tmp = r->out;
    r->out = r->pending;
    r->pending = tmp;
    ms_notes_clear(&r->pending);
    rec->notes = &r->out;
    rec->number = ++r->n;
}

/* ---- reading ------------------------------------------------------------------------------------ */

static int64_t source_read(ms_reader *r, uint8_t *dst, size_t n, uint64_t off) {
    /* capture/reader.py pread: fewer bytes only at the end of the file */
    size_t got = 0;
    while (got < n) {
        int err = 0;
        int64_t k = r->src.read(r->src.ctx, dst + got, n - got, off + got, &err);
        if (k < 0) {
            if (err == EINTR)
                continue;
            r->io_errno = err ? err : EIO;
            return -1;
        }
        if (k == 0)
            break;
        got += (size_t)k;
    }
    return (int64_t)got;
}

int ms_read_at(ms_reader *r, ms_window *w, uint64_t off, size_t n) {
    size_t want = 0;
    if (off < r->size)
        want = r->size - off < n ? (size_t)(r->size - off) : n;
    w->base = off;
    w->len = 0;
    if (want == 0)
        return MS_READ_OK;
    if (want > w->cap || (w->cap > 8 * (size_t)MS_WINDOW && want <= MS_WINDOW)) {
        /* grow to the record being read, or give back what one long record took */
        uint8_t *p = realloc(w->data, want);
        if (p == NULL)
            return MS_READ_NOMEM;
        w->data = p;
        w->cap = want;
    }
    int64_t got = source_read(r, w->data, want, off);
    if (got < 0)
        return MS_READ_IO;
    w->len = (size_t)got;
    if ((size_t)got < want)
        r->size = off + (uint64_t)got; /* the file shrank */
    return MS_READ_OK;
}

int64_t ms_read_small(ms_reader *r, uint64_t off, size_t n, uint8_t *dst) {
    size_t want = 0;
    if (off < r->size)
        want = r->size - off < n ? (size_t)(r->size - off) : n;
    if (want == 0)
        return 0;
    int64_t got = source_read(r, dst, want, off);
    if (got < 0)
        return MS_READ_IO;
    if ((size_t)got < want)
        r->size = off + (uint64_t)got;
    return got;
}

void ms_shrink_notes(ms_reader *r, ms_notes *ns) {
    if (r->size >= r->opened_size)
        return;
    ms_notes_add(ns, MS_NOTE_RECORD_TRUNCATED, (int64_t)r->size,
                 "the file shrank while it was read: its bytes ended at offset %llu of the %llu it had when "
                 "opened; the rest is lost",
                 (unsigned long long)r->size, (unsigned long long)r->opened_size);
}

int ms_reader_fail(ms_reader *r, ms_record *rec, uint64_t offset, int rc, int64_t linktype) {
    if (rc == MS_READ_NOMEM) {
        r->pending.failed = 1;
        return -1;
    }
    r->position = r->size;
    r->done = 1;
    ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)offset,
                 "unreadable from offset %llu on (OSError: [Errno %d] %s); rest skipped", (unsigned long long)offset,
                 r->io_errno, strerror(r->io_errno));
    ms_record_set(rec, linktype, NULL, 0, offset, 0);
    ms_reader_emit(r, rec);
    return 1;
}

static int64_t memory_read(void *ctx, uint8_t *dst, size_t n, uint64_t off, int *err) {
    ms_memory_file *f = ctx;
    f->reads++;
    if (f->fail_at && f->reads == f->fail_at) {
        *err = EIO;
        return -1;
    }
    uint64_t size = f->size;
    if (f->shrink_after && f->reads > f->shrink_after && f->shrink_to < size)
        size = f->shrink_to;
    if (off >= size)
        return 0;
    size_t k = size - off < n ? (size_t)(size - off) : n;
    memcpy(dst, f->data + off, k);
    return (int64_t)k;
}

ms_source ms_memory_source(ms_memory_file *f) {
    ms_source s = {memory_read, f};
    return s;
}

#if defined(_WIN32)
#include <io.h>
static int64_t fd_read(void *ctx, uint8_t *dst, size_t n, uint64_t off, int *err) {
    int fd = *(int *)ctx;
    if (_lseeki64(fd, (long long)off, SEEK_SET) < 0) {
        *err = errno;
        return -1;
    }
    int k = _read(fd, dst, n > 0x40000000u ? 0x40000000u : (unsigned)n);
    if (k < 0)
        *err = errno;
    return k;
}
#else
#include <unistd.h>
static int64_t fd_read(void *ctx, uint8_t *dst, size_t n, uint64_t off, int *err) {
    ssize_t k = pread(*(int *)ctx, dst, n > 0x40000000u ? 0x40000000u : n, (off_t)off);
    if (k < 0)
        *err = errno;
    return (int64_t)k;
}
#endif

ms_source ms_fd_source(int *fd) {
    ms_source s = {fd_read, fd};
    return s;
}

/* ---- the reader ---------------------------------------------------------------------------------- */

static void window_free(ms_window *w) {
    free(w->data);
    memset(w, 0, sizeof *w);
}

void ms_reader_init(ms_reader *r, ms_source src, uint64_t size, int kind) {
    memset(r, 0, sizeof *r);
    r->src = src;
    r->size = r->opened_size = size;
    r->window = MS_WINDOW;
    r->kind = kind;
    r->last_sec = -1;
    r->last_ts = -1;
    ms_notes_init(&r->pending);
    ms_notes_init(&r->out);
}

void ms_reader_free(ms_reader *r) {
    ms_notes_free(&r->pending);
    ms_notes_free(&r->out);
    window_free(&r->win);
    window_free(&r->aux);
    free(r->ifaces);
    r->ifaces = NULL;
    r->nifaces = r->capifaces = 0;
}

/* RawReader._records: chunks of CHUNK bytes, then the shrink note on an empty record of its own */
static int raw_next(ms_reader *r, ms_record *rec) {
    if (r->pos < r->size) {
        int rc = ms_read_at(r, &r->win, r->pos, RAW_CHUNK);
        if (rc != MS_READ_OK)
            return ms_reader_fail(r, rec, r->pos, rc, MS_LINKTYPE_RAW);
        if (r->win.len) {
            ms_record_set(rec, MS_LINKTYPE_RAW, r->win.data, r->win.len, r->pos, r->win.len);
            ms_reader_emit(r, rec);
            r->pos += r->win.len;
            r->position = r->pos;
            return 1;
        }
    }
    r->done = 1;
    ms_shrink_notes(r, &r->pending);
    if (r->pending.n == 0)
        return 0;
    ms_record_set(rec, MS_LINKTYPE_RAW, NULL, 0, r->pos, 0);
    ms_reader_emit(r, rec);
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

int ms_reader_extend(ms_reader *r, uint64_t size) {
    if (r->kind != MS_KIND_PCAP || size < r->size)
        return -1;
    if (r->done) {
        if (!r->header_ok || r->pos != r->size || r->pending.n != 0 || r->io_errno)
            return -1;
        r->done = 0;
    }
    r->size = r->opened_size = size;
    return 0;
}

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
