/* QGroundControl / MAVProxy telemetry logs, as mavscope/capture/tlog.py reads them:
 * [8-byte big-endian µs timestamp][one MAVLink frame], repeated; broken entries are skipped by
 * looking for the next plausible entry. */
#include "capture.h"

#include <string.h>

#define TS_MIN (946684800ull * 1000000ull)
#define TS_MAX (4102444800ull * 1000000ull)
#define RESYNC_BEHIND (3600ull * 1000000ull)
#define RESYNC_AHEAD (86400ull * 1000000ull)

/* frame_length: size of the frame whose STX is at p, or -1 */
static int64_t frame_length(const ms_reader *r, size_t p) {
    if (r->size < 3 || p > r->size - 3)
        return -1;
    const uint8_t *b = r->buf + p;
    if (b[0] == 0xFD)
        return 12 + b[1] + ((b[2] & 1) ? 13 : 0);
    if (b[0] == 0xFE)
        return 8 + b[1];
    return -1;
}

/* entry_end: end of a plausible, complete entry at p with a timestamp in [lo, hi), or -1 */
static int64_t entry_end(const ms_reader *r, size_t p, uint64_t lo, uint64_t hi) {
    if (r->size < 11 || p > r->size - 11)
        return -1;
    uint64_t ts = ms_be64(r->buf + p);
    if (!(lo <= ts && ts < hi))
        return -1;
    int64_t flen = frame_length(r, p + 8);
    if (flen < 0 || (uint64_t)p + 8 + (uint64_t)flen > r->size)
        return -1;
    return (int64_t)p + 8 + flen;
}

/* _followed: an entry ending at p is followed by a plausible entry, a cut one at the end, or the end */
static int followed(const ms_reader *r, size_t p, uint64_t lo, uint64_t hi) {
    if (r->size - p < 11)
        return 1;
    uint64_t ts = ms_be64(r->buf + p);
    uint8_t stx = r->buf[p + 8];
    if (!(lo <= ts && ts < hi) || (stx != 0xFE && stx != 0xFD))
        return 0;
    if (entry_end(r, p, lo, hi) >= 0)
        return 1;
    return (int64_t)p + 8 + frame_length(r, p + 8) > (int64_t)r->size;
}

/* find_entry: offset of the next plausible entry at or after `start` that is followed by another one
 * (or the end), its timestamp near last_ts when that is known; or -1 */
static int64_t find_entry(const ms_reader *r, size_t start, int64_t last_ts) {
    uint64_t lo = TS_MIN, hi = TS_MAX;
    if (last_ts >= 0) {
        uint64_t t = (uint64_t)last_ts;
        if (t >= RESYNC_BEHIND && t - RESYNC_BEHIND > lo)
            lo = t - RESYNC_BEHIND;
        if (t + RESYNC_AHEAD < hi)
            hi = t + RESYNC_AHEAD;
    }
    const uint8_t *buf = r->buf;
    const size_t size = r->size;
    for (size_t q = start + 8; q < size; q++) {
        if (buf[q] != 0xFD && buf[q] != 0xFE)
            continue;
        size_t p = q - 8;
        int64_t end = entry_end(r, p, lo, hi);
        if (end >= 0 && followed(r, (size_t)end, lo, hi))
            return (int64_t)p;
    }
    return -1;
}

static void tlog_record(ms_record *rec, uint64_t number, int has_time, uint64_t ts, size_t start, size_t len,
                        uint64_t orig) {
    memset(rec, 0, sizeof *rec);
    rec->number = number;
    rec->time_kind = has_time ? MS_TIME_DOUBLE : MS_TIME_NONE;
    rec->time = (double)ts / 1e6;
    rec->linktype = MS_LINKTYPE_TLOG;
    rec->start = start;
    rec->len = len;
    rec->orig_len = orig;
}

int ms_tlog_next(ms_reader *r, ms_record *rec) {
    const uint8_t *buf = r->buf;
    const size_t size = r->size;
    for (;;) {
        const size_t pos = r->pos;
        if (pos >= size)
            break;
        if (size - pos >= 11) {
            uint64_t ts = ms_be64(buf + pos);
            uint8_t stx = buf[pos + 8];
            int64_t end = -1;
            if (stx == 0xFD)
                end = (int64_t)pos + 20 + buf[pos + 9] + ((buf[pos + 10] & 1) ? 13 : 0);
            else if (stx == 0xFE)
                end = (int64_t)pos + 16 + buf[pos + 9];
            if (end >= 0 && TS_MIN <= ts && ts < TS_MAX) {
                if ((uint64_t)end <= size) {
                    tlog_record(rec, r->n + 1, 1, ts, pos + 8, (size_t)end - pos - 8, (uint64_t)end - pos - 8);
                    ms_reader_emit(r, rec);
                    r->last_ts = (int64_t)ts;
                    r->pos = (size_t)end;
                    return 1;
                }
                int64_t q = find_entry(r, pos + 1, r->last_ts);
                if (q < 0) { /* a cut last entry */
                    ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                                 "tlog entry at offset %zu has %zu of %lld frame bytes: file cut short", pos,
                                 size - pos - 8, (long long)(end - (int64_t)pos - 8));
                    tlog_record(rec, r->n + 1, 1, ts, pos + 8, size - pos - 8, (uint64_t)(end - (int64_t)pos - 8));
                    ms_reader_emit(r, rec);
                    r->done = 1;
                    r->pos = size;
                    return 1;
                }
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "broken tlog entry at offset %zu: %zu bytes skipped", pos, (size_t)q - pos);
                r->pos = (size_t)q;
                continue;
            }
        }
        int64_t q = find_entry(r, pos + 1, r->last_ts);
        if (q < 0) {
            if (size - pos < 11) { /* too short for an entry header: a cut last entry */
                int64_t ts = pos + 8 <= size ? (int64_t)ms_be64(buf + pos) : -1;
                int has_time = ts >= 0 && (uint64_t)ts >= TS_MIN && (uint64_t)ts < TS_MAX;
                ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                             "file ends %zu bytes into a tlog entry", size - pos);
                size_t start = pos + 8 < size ? pos + 8 : size;
                tlog_record(rec, r->n + 1, has_time, has_time ? (uint64_t)ts : 0, start, size - start, size - start);
                ms_reader_emit(r, rec);
                r->done = 1;
                r->pos = size;
                return 1;
            }
            ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                         "broken tlog entry at offset %zu; no later entry found, %zu bytes skipped", pos, size - pos);
            break;
        }
        ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                     "broken tlog entry at offset %zu: %zu bytes skipped", pos, (size_t)q - pos);
        r->pos = (size_t)q;
    }
    r->done = 1;
    if (r->pending.n == 0)
        return 0;
    memset(rec, 0, sizeof *rec);
    rec->number = r->n + 1;
    rec->linktype = MS_LINKTYPE_TLOG;
    rec->start = r->pos + 8 < size ? r->pos + 8 : size;
    ms_reader_emit(r, rec);
    return 1;
}
