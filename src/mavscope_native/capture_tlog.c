/* QGroundControl / MAVProxy telemetry logs, a port of mavscope/capture/tlog.py, a window of the file at a
 * time: [8-byte big-endian µs timestamp][one MAVLink frame], repeated; entries of bytes that are not
 * MAVLink (console text MAVProxy logged) end where the next plausible timestamp starts; broken entries
 * are skipped by looking for the next plausible entry. The comments name the Python they mirror. */
#include "capture.h"

#include <string.h>

#define STX_V1 0xFE
#define STX_V2 0xFD
#define TS_MIN (946684800ll * 1000000ll)
#define TS_MAX (4102444800ll * 1000000ll)
#define RESYNC_BEHIND (3600ll * 1000000ll)
#define RESYNC_AHEAD (86400ll * 1000000ll)
#define LOOKAHEAD (2 * (8 + 12 + 255 + 2 + 13)) /* two entries: what deciding on an entry may look at */
#define TEXT_MAX (LOOKAHEAD - 16)               /* bytes a non-MAVLink entry may hold */

/* timestamps as Python's ints: a big-endian u64 compared with signed bounds */
static int in_range(uint64_t ts, int64_t lo, int64_t hi) {
    return ts < (1ull << 62) && lo <= (int64_t)ts && (int64_t)ts < hi;
}

/* frame_length: length of the frame whose STX is at buf[p] (from its header), or -1 */
static int64_t frame_length(const uint8_t *buf, int64_t p, int64_t size) {
    if (p + 3 > size)
        return -1;
    if (buf[p] == STX_V2)
        return 12 + buf[p + 1] + ((buf[p + 2] & 1) ? 13 : 0);
    if (buf[p] == STX_V1)
        return 8 + buf[p + 1];
    return -1;
}

/* entry_end: end of a plausible, complete entry at buf[p] with a timestamp in [lo, hi), or -1 */
static int64_t entry_end(const uint8_t *buf, int64_t p, int64_t size, int64_t lo, int64_t hi) {
    if (p < 0 || p + 11 > size)
        return -1;
    if (!in_range(ms_be64(buf + p), lo, hi))
        return -1;
    int64_t flen = frame_length(buf, p + 8, size);
    if (flen < 0 || p + 8 + flen > size)
        return -1;
    return p + 8 + flen;
}

/* _followed: an entry ending at p is followed by a plausible entry, a cut one at the end, or the end */
static int followed(const uint8_t *buf, int64_t p, int64_t size, int64_t lo, int64_t hi) {
    if (size - p < 11)
        return 1;
    if (!in_range(ms_be64(buf + p), lo, hi) || (buf[p + 8] != STX_V1 && buf[p + 8] != STX_V2))
        return 0;
    return entry_end(buf, p, size, lo, hi) >= 0 || p + 8 + frame_length(buf, p + 8, size) > size;
}

/* find_entry: offset of the next plausible entry at or after `start` (its STX before `stop`), followed by
 * another one (or the end), its timestamp near last_ts when that is known; or -1 */
static int64_t find_entry(const uint8_t *buf, size_t blen, int64_t size, int64_t start, int64_t last_ts,
                          int64_t stop) {
    int64_t lo = TS_MIN, hi = TS_MAX;
    if (last_ts >= 0) {
        if (last_ts - RESYNC_BEHIND > lo)
            lo = last_ts - RESYNC_BEHIND;
        if (last_ts + RESYNC_AHEAD < hi)
            hi = last_ts + RESYNC_AHEAD;
    }
    if (stop > (int64_t)blen)
        stop = (int64_t)blen;
    for (int64_t q = start + 8; q < stop; q++) {
        if (buf[q] != STX_V2 && buf[q] != STX_V1)
            continue;
        int64_t p = q - 8;
        int64_t end = entry_end(buf, p, size, lo, hi);
        if (end >= 0 && followed(buf, end, size, lo, hi))
            return p;
    }
    return -1;
}

/* near: whether ts is a plausible entry timestamp after one at last_ts (-1: the first entry) */
static int near(uint64_t ts, int64_t last_ts) {
    if (!in_range(ts, TS_MIN, TS_MAX))
        return 0;
    return last_ts < 0 || (last_ts - RESYNC_BEHIND <= (int64_t)ts && (int64_t)ts <= last_ts + RESYNC_AHEAD);
}

/* whether a MAVLink entry starts at buf[q]: an STX after a timestamp near ts (tlog.py's fast-path test) */
static int entry_starts(const uint8_t *buf, int64_t q, uint64_t ts) {
    return (buf[q + 8] == STX_V1 || buf[q + 8] == STX_V2) && near(ms_be64(buf + q), (int64_t)ts);
}

/* cut_at: where a whole entry starts inside the entry at buf[p] (timestamp ts) whose frame ends at `end` where
 * no timestamp is, or -1 (tlog.py's cut_at) */
static int64_t cut_at(const uint8_t *buf, size_t blen, int64_t p, int64_t end, uint64_t ts, int64_t size) {
    if (end + 9 > size || entry_starts(buf, end, ts))
        return -1;
    return find_entry(buf, blen, size, p + 9, (int64_t)ts, end + 8);
}

/* text_entry_end: end of the entry at buf[p] whose bytes are not a MAVLink frame: the first offset after
 * at least one byte where an entry with a timestamp near this one's starts, or the end of the file (`final`:
 * `stop` is the end); within TEXT_MAX bytes and before `stop`; -1 if there is none */
static int64_t text_entry_end(const uint8_t *buf, int64_t p, int64_t stop, int final) {
    if (p + 9 > stop)
        return -1;
    const int64_t ts = (int64_t)ms_be64(buf + p); /* near() bounds it: a first entry's ts is plausible */
    int64_t last = stop - 8 < p + 8 + TEXT_MAX ? stop - 8 : p + 8 + TEXT_MAX;
    for (int64_t q = p + 9; q <= last; q++)
        if (near(ms_be64(buf + q), ts))
            return q;
    if (final && stop - p - 8 <= TEXT_MAX)
        return stop;
    return -1;
}

/* TlogReader._find: find_entry over the file from `start`, a window at a time (the reader's window); the
 * offset in *found (-1 if none); 0 or a negative MS_READ_* */
static int find(ms_reader *r, uint64_t start, int64_t last_ts, int64_t *found) {
    for (;;) {
        ms_window *w = &r->win;
        if (start < w->base || (start + LOOKAHEAD >= w->base + w->len && w->base + w->len < r->size)) {
            int rc = ms_window_at(r, w, start, 2 * LOOKAHEAD);
            if (rc != MS_READ_OK)
                return rc;
        }
        const uint64_t size = r->size;
        const int final = w->base + w->len >= size;
        const int64_t limit = final ? (int64_t)w->len : (int64_t)w->len - LOOKAHEAD;
        const int64_t rsize = final ? (int64_t)size - (int64_t)w->base : (int64_t)w->len;
        int64_t q = find_entry(w->data, w->len, rsize, (int64_t)(start - w->base), last_ts, limit + 8);
        if (q >= 0) {
            *found = (int64_t)w->base + q;
            return 0;
        }
        if (final) {
            *found = -1;
            return 0;
        }
        start = w->base + (uint64_t)limit;
    }
}

static void entry(ms_reader *r, ms_record *rec, const uint8_t *data, size_t len, uint64_t offset, uint64_t orig,
                  int has_time, uint64_t ts) {
    ms_record_set(rec, MS_LINKTYPE_TLOG, data, len, offset, orig);
    if (has_time) {
        rec->time_kind = MS_TIME_DOUBLE;
        rec->time = (double)ts / 1e6;
    }
    ms_reader_emit(r, rec);
}

#define FAIL(rc) return ms_reader_fail(r, rec, r->pos, (rc), MS_LINKTYPE_TLOG)

/* The end of a cut last entry: its bytes from `start` to the end, read into the second window */
static int cut_entry(ms_reader *r, ms_record *rec, uint64_t start, uint64_t want, uint64_t orig, int has_time,
                     uint64_t ts) {
    int rc = ms_read_at(r, &r->aux, start, (size_t)want);
    if (rc != MS_READ_OK)
        FAIL(rc);
    r->done = 1;
    entry(r, rec, r->aux.data, r->aux.len, start, orig, has_time, ts);
    return 1;
}

/* TlogReader._records, one record per call */
int ms_tlog_next(ms_reader *r, ms_record *rec) {
    if (!r->started) {
        r->started = 1;
        int rc = ms_window_at(r, &r->win, 0, 2 * LOOKAHEAD);
        if (rc != MS_READ_OK)
            FAIL(rc);
    }
    for (;;) {
        uint64_t pos = r->pos;
        uint64_t size = r->size;
        if (pos >= size)
            break;
        uint64_t base = r->win.base;
        const uint8_t *buf = r->win.data;
        size_t blen = r->win.len;
        int64_t p = (int64_t)(pos - base);
        /* the common case: a complete entry whose frame fits the window, decidable in it */
        const int64_t last = base + blen < size ? (int64_t)blen - LOOKAHEAD : (int64_t)blen - 11;
        if (p <= last) {
            uint64_t ts = ms_be64(buf + p);
            const int64_t flen = frame_length(buf, p + 8, (int64_t)blen);
            int64_t end = flen < 0 ? -1 : p + 8 + flen;
            if (end >= 0 && end <= (int64_t)blen && in_range(ts, TS_MIN, TS_MAX)
                && !(end + 9 <= (int64_t)blen && !entry_starts(buf, end, ts))) {
                /* (no entry starts where it ends: the slow path looks for one inside it) */
                r->last_ts = (int64_t)ts;
                entry(r, rec, buf + p + 8, (size_t)(end - p - 8), base + (uint64_t)p + 8, (uint64_t)(end - p - 8), 1, ts);
                r->pos = base + (uint64_t)end;
                if (!(rec->number & 1023))
                    r->position = r->pos;
                return 1;
            }
        }
        r->position = pos;
        if (p + LOOKAHEAD > (int64_t)blen && base + blen < size) { /* near the window's end: read on */
            int rc = ms_window_at(r, &r->win, pos, 2 * LOOKAHEAD);
            if (rc != MS_READ_OK)
                FAIL(rc);
            continue;
        }
        if (pos + 9 <= size && buf[p + 8] != STX_V1 && buf[p + 8] != STX_V2 && near(ms_be64(buf + p), r->last_ts)) {
            int64_t q = text_entry_end(buf, p, (int64_t)blen, base + blen >= size);
            if (q >= 0) { /* an entry of bytes that are not MAVLink: the dissector says what they are */
                uint64_t ts = ms_be64(buf + p);
                r->last_ts = (int64_t)ts;
                entry(r, rec, buf + p + 8, (size_t)(q - p - 8), base + (uint64_t)p + 8, (uint64_t)(q - p - 8), 1, ts);
                r->pos = base + (uint64_t)q;
                r->position = r->pos;
                return 1;
            }
        }
        int64_t q;
        if (pos + 11 <= size) {
            uint64_t ts = ms_be64(buf + p);
            const int64_t flen = frame_length(buf, p + 8, (int64_t)blen); /* the frame length the entry announces */
            int64_t end = flen < 0 ? -1 : p + 8 + flen;
            if (end >= 0 && in_range(ts, TS_MIN, TS_MAX)) {
                const int64_t valid = base + blen >= size ? (int64_t)(size - base) : (int64_t)blen;
                q = cut_at(buf, blen, p, end, ts, valid);
                if (q >= 0) { /* cut short where a whole entry starts inside it */
                    r->last_ts = (int64_t)ts;
                    ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                                 "tlog entry at offset %llu has %lld of %lld frame bytes: the entry at offset %llu "
                                 "starts inside it", (unsigned long long)pos, (long long)(q - p - 8), (long long)flen,
                                 (unsigned long long)(base + (uint64_t)q));
                    entry(r, rec, buf + p + 8, (size_t)(q - p - 8), base + (uint64_t)p + 8, (uint64_t)flen, 1, ts);
                    r->pos = base + (uint64_t)q;
                    r->position = r->pos;
                    return 1;
                }
                if (base + (uint64_t)end <= size) {
                    r->last_ts = (int64_t)ts;
                    r->position = base + (uint64_t)end;
                    entry(r, rec, buf + p + 8, (size_t)(end - p - 8), base + (uint64_t)p + 8, (uint64_t)(end - p - 8), 1,
                          ts);
                    r->pos = base + (uint64_t)end;
                    return 1;
                }
                int rc = find(r, pos + 1, r->last_ts, &q);
                if (rc != 0)
                    FAIL(rc);
                size = r->size;
                if (q < 0) { /* a cut last entry */
                    r->position = size;
                    ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                                 "tlog entry at offset %llu has %lld of %lld frame bytes: file cut short",
                                 (unsigned long long)pos, (long long)size - (long long)pos - 8, (long long)flen);
                    ms_shrink_notes(r, &r->pending);
                    return cut_entry(r, rec, pos + 8, size > pos + 8 ? size - pos - 8 : 0, (uint64_t)flen, 1, ts);
                }
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "broken tlog entry at offset %llu: %llu bytes skipped", (unsigned long long)pos,
                             (unsigned long long)((uint64_t)q - pos));
                r->pos = (uint64_t)q;
                continue;
            }
        }
        int rc = find(r, pos + 1, r->last_ts, &q);
        if (rc != 0)
            FAIL(rc);
        size = r->size;
        if (q < 0) {
            if (size < pos + 11) { /* too short for an entry header: a cut last entry */
                uint8_t stamp[8];
                int64_t got = ms_read_small(r, pos, 8, stamp);
                if (got < 0)
                    FAIL((int)got);
                uint64_t ts = got == 8 ? ms_be64(stamp) : 0;
                int has_time = got == 8 && in_range(ts, TS_MIN, TS_MAX);
                r->position = r->size;
                ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos, "file ends %lld bytes into a tlog entry",
                             (long long)size - (long long)pos);
                ms_shrink_notes(r, &r->pending);
                /* Python goes on with its `size` from before the stamp was read */
                uint64_t start = pos + 8 < size ? pos + 8 : size;
                return cut_entry(r, rec, start, size - start, size - start, has_time, ts);
            }
            ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                         "broken tlog entry at offset %llu; no later entry found, %lld bytes skipped",
                         (unsigned long long)pos, (long long)size - (long long)pos);
            break;
        }
        ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos, "broken tlog entry at offset %llu: %llu bytes skipped",
                     (unsigned long long)pos, (unsigned long long)((uint64_t)q - pos));
        r->pos = (uint64_t)q;
    }
    r->done = 1;
    ms_shrink_notes(r, &r->pending);
    r->position = r->size;
    if (r->pending.n == 0)
        return 0;
    uint64_t at = r->pos + 8 < r->size ? r->pos + 8 : r->size;
    ms_record_set(rec, MS_LINKTYPE_TLOG, NULL, 0, at, 0);
    ms_reader_emit(r, rec);
    return 1;
}
