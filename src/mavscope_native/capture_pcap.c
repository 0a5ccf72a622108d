/* Classic libpcap files, a port of mavscope/capture/pcap.py (both byte orders, µs and ns), a window of
 * the file at a time. The comments name the Python they mirror. */
#include "capture.h"

#include <string.h>

#define MAGIC_US 0xA1B2C3D4u
#define MAGIC_NS 0xA1B23C4Du
#define MIN_MAX_RECORD 262144u
#define RESYNC_WINDOW 86400

/* PcapReader.__init__: the global header from the first 40 bytes read; 0, or a negative MS_READ_* */
static int pcap_init(ms_reader *r) {
    uint8_t head[40];
    int64_t got = ms_read_small(r, 0, 40, head);
    if (got < 0)
        return (int)got;
    r->big = 0;
    if (got >= 4) { /* sniff_pcap: "<" first, then ">" */
        uint32_t le = ms_le32(head), be = ms_be32(head);
        if (!(le == MAGIC_US || le == MAGIC_NS) && (be == MAGIC_US || be == MAGIC_NS))
            r->big = 1;
    }
    uint32_t magic = got >= 4 ? ms_u32(head, r->big) : MAGIC_US;
    r->nanosecond = magic == MAGIC_NS;
    r->snaplen = 0;
    r->linktype = 1;
    r->header_ok = got >= 24;
    r->last_sec = got >= 40 ? (int64_t)ms_u32(head + 24, r->big) : -1; /* _first_sec */
    if (r->header_ok) {
        r->snaplen = ms_u32(head + 16, r->big);
        r->linktype = ms_u32(head + 20, r->big) & 0xFFFFu;
    }
    return 0;
}

/* PcapReader._plausible: 1, 0, or a negative MS_READ_* */
static int plausible(ms_reader *r, uint64_t p, int64_t last_sec, uint64_t maxlen, uint32_t div) {
    for (int depth = 0; depth < 2; depth++) {
        if (p == r->size && depth)
            return 1;
        if (p + 16 > r->size)
            return 0;
        uint8_t h[16];
        int64_t got = ms_read_small(r, p, 16, h);
        if (got < 0)
            return (int)got;
        if (got < 16)
            return 0;
        uint32_t sec = ms_u32(h, r->big), frac = ms_u32(h + 4, r->big);
        uint32_t incl = ms_u32(h + 8, r->big), orig = ms_u32(h + 12, r->big);
        if (frac >= div || incl > maxlen || orig < incl || (uint64_t)orig > 16 * maxlen)
            return 0;
        if (last_sec >= 0 && !(last_sec - RESYNC_WINDOW / 24 <= (int64_t)sec && (int64_t)sec <= last_sec + RESYNC_WINDOW))
            return 0;
        if (last_sec < 0 && !(0 < sec && (uint64_t)sec < 4102444800u))
            return 0;
        last_sec = sec;
        p += 16 + (uint64_t)incl;
        if (p > r->size)
            return 0;
    }
    return 1;
}

/* PcapReader._resync: the next plausible record header after `pos` in *found (-1 if none); 0, or a
 * negative MS_READ_* */
static int resync(ms_reader *r, uint64_t pos, int64_t last_sec, uint64_t maxlen, uint32_t div, int64_t *found) {
    const int64_t lo = last_sec >= 0 ? last_sec - RESYNC_WINDOW / 24 : 1;
    const int64_t hi = last_sec >= 0 ? last_sec + RESYNC_WINDOW : 4102444799;
    const uint64_t big = 16 * maxlen;
    uint64_t p = pos + 1;
    *found = -1;
    while (p + 15 < r->size) {
        int rc = ms_window_at(r, &r->aux, p, 0);
        if (rc != MS_READ_OK)
            return rc;
        const uint8_t *buf = r->aux.data;
        uint64_t avail = r->aux.len < r->size - p ? r->aux.len : r->size - p;
        int64_t stop = (int64_t)avail - 15; /* offsets p + rel whose 16-byte header is in the window */
        for (int64_t rel = 0; rel < stop; rel++) {
            const uint8_t *h = buf + rel;
            uint32_t sec = ms_u32(h, r->big), frac = ms_u32(h + 4, r->big);
            uint32_t incl = ms_u32(h + 8, r->big), orig = ms_u32(h + 12, r->big);
            if (frac < div && incl <= maxlen && incl <= orig && orig <= big && lo <= (int64_t)sec && (int64_t)sec <= hi) {
                int ok = plausible(r, p + (uint64_t)rel, last_sec, maxlen, div);
                if (ok < 0)
                    return ok;
                if (ok) {
                    *found = (int64_t)(p + (uint64_t)rel);
                    return 0;
                }
            }
        }
        p += stop > 1 ? (uint64_t)stop : 1;
    }
    return 0;
}

static void set_time(ms_record *rec, uint32_t sec, uint32_t frac, uint32_t div) {
    rec->time_kind = MS_TIME_DOUBLE;
    rec->time = (double)sec + (double)frac / (double)div;
}

/* PcapReader._records, one record per call */
int ms_pcap_next(ms_reader *r, ms_record *rec) {
    if (!r->started) {
        r->started = 1;
        int rc = pcap_init(r);
        if (rc != 0) /* Python raises CaptureError from __init__; the glue has opened the file already */
            return ms_reader_fail(r, rec, 0, rc, 1);
        if (!r->header_ok) {
            r->done = 1;
            r->position = r->size;
            if (r->size)
                ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, 0, "file ends %llu bytes into the 24-byte pcap header",
                             (unsigned long long)r->size);
            ms_shrink_notes(r, &r->pending);
            if (r->pending.n == 0)
                return 0;
            ms_record_set(rec, r->linktype, NULL, 0, 0, 0);
            ms_reader_emit(r, rec);
            return 1;
        }
        r->pos = 24;
        rc = ms_window_at(r, &r->win, 24, 0);
        if (rc != MS_READ_OK)
            return ms_reader_fail(r, rec, r->pos, rc, r->linktype);
    }
    const int64_t lt = r->linktype;
    const uint32_t div = r->nanosecond ? 1000000000u : 1000000u;
    const uint64_t maxlen = r->snaplen > MIN_MAX_RECORD ? r->snaplen : MIN_MAX_RECORD;
    for (;;) {
        const uint64_t pos = r->pos;
        const uint64_t base = r->win.base;
        const uint8_t *buf = r->win.data;
        const size_t blen = r->win.len;
        if (r->pending.n == 0 && pos >= base && pos - base + 16 <= blen) {
            /* the common case: a complete, unsnapped record in the window while there is nothing to report */
            const size_t p = (size_t)(pos - base);
            const uint8_t *h = buf + p;
            uint32_t sec = ms_u32(h, r->big), frac = ms_u32(h + 4, r->big);
            uint32_t incl = ms_u32(h + 8, r->big), orig = ms_u32(h + 12, r->big);
            uint64_t end = (uint64_t)p + 16 + incl;
            if (!(end > blen || incl > maxlen || orig != incl)) {
                ms_record_set(rec, lt, h + 16, incl, base + p + 16, orig);
                set_time(rec, sec, frac, div);
                ms_reader_emit(r, rec);
                r->pos = base + end;
                if (!(rec->number & 1023)) {
                    r->position = r->pos;
                    r->last_sec = sec; /* resynchronisation looks for timestamps near this one */
                }
                return 1;
            }
        }
        r->position = pos;
        const uint64_t have = base + blen; /* the window holds the file's bytes up to here */
        uint64_t size = r->size;
        if (pos + 16 > have && have < size) { /* the next header crosses the window: read on from it */
            int rc = ms_window_at(r, &r->win, pos, 0);
            if (rc != MS_READ_OK)
                return ms_reader_fail(r, rec, pos, rc, lt);
            continue;
        }
        if (pos + 16 > size) {
            r->done = 1;
            if (pos < size)
                ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                             "file ends %llu bytes into a 16-byte record header at offset %llu",
                             (unsigned long long)(size - pos), (unsigned long long)pos);
            ms_shrink_notes(r, &r->pending);
            r->position = size;
            if (r->pending.n == 0)
                return 0;
            ms_record_set(rec, lt, NULL, 0, pos, 0);
            ms_reader_emit(r, rec);
            return 1;
        }
        const uint8_t *h = buf + (pos - base);
        uint32_t sec = ms_u32(h, r->big), frac = ms_u32(h + 4, r->big);
        uint32_t incl = ms_u32(h + 8, r->big), orig = ms_u32(h + 12, r->big);
        if (incl > maxlen) {
            int64_t found;
            int rc = resync(r, pos, r->last_sec, maxlen, div, &found);
            if (rc != 0)
                return ms_reader_fail(r, rec, pos, rc, lt);
            size = r->size;
            if (found < 0) {
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "corrupt record header at offset %llu (length %u); no later record found, %lld bytes "
                             "skipped",
                             (unsigned long long)pos, (unsigned)incl, (long long)size - (long long)pos);
                r->pos = size;
                continue;
            }
            ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                         "corrupt record header at offset %llu: %llu bytes skipped", (unsigned long long)pos,
                         (unsigned long long)((uint64_t)found - pos));
            r->pos = (uint64_t)found;
            continue;
        }
        const uint64_t start = pos + 16;
        uint64_t end = start + incl;
        if (end > have && have < size) { /* the record crosses the window: read it whole */
            int rc = ms_window_at(r, &r->win, pos, 16 + (size_t)incl);
            if (rc != MS_READ_OK)
                return ms_reader_fail(r, rec, pos, rc, lt);
            continue;
        }
        r->last_sec = sec;
        if (end > size) {
            ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                         "record at offset %llu has %llu of %u bytes: file cut short", (unsigned long long)pos,
                         (unsigned long long)(size - start), (unsigned)incl);
            end = size;
        }
        uint64_t o = orig;
        if (orig < incl)
            o = incl; /* lenient: some writers leave orig_len 0 or short */
        else if (orig > incl)
            ms_notes_add(&r->pending, MS_NOTE_RECORD_SNAPPED, (int64_t)start, "%u of %u bytes captured", (unsigned)incl,
                         (unsigned)orig);
        r->position = end;
        ms_record_set(rec, lt, buf + (start - base), (size_t)(end - start), start, o);
        set_time(rec, sec, frac, div);
        ms_reader_emit(r, rec);
        r->pos = end;
        return 1;
    }
}
