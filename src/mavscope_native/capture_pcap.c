/* Classic libpcap files, as mavscope/capture/pcap.py reads them (both byte orders, µs and ns). */
#include "capture.h"

#include <string.h>

#define MAGIC_US 0xA1B2C3D4u
#define MAGIC_NS 0xA1B23C4Du
#define MIN_MAX_RECORD 262144u
#define RESYNC_WINDOW 86400

int ms_pcap_init(ms_reader *r) {
    const uint8_t *buf = r->buf;
    const size_t size = r->size;
    r->big = 0;
    if (size >= 4) { /* sniff_pcap: "<" first, then ">" */
        uint32_t le = ms_le32(buf), be = ms_be32(buf);
        if (!(le == MAGIC_US || le == MAGIC_NS) && (be == MAGIC_US || be == MAGIC_NS))
            r->big = 1;
    }
    uint32_t magic = size >= 4 ? ms_u32(buf, r->big) : MAGIC_US;
    r->nanosecond = magic == MAGIC_NS;
    r->snaplen = 0;
    r->linktype = 1;
    r->header_ok = size >= 24;
    if (r->header_ok) {
        r->snaplen = ms_u32(buf + 16, r->big);
        r->linktype = ms_u32(buf + 20, r->big) & 0xFFFFu;
    }
    r->pos = 24;
    r->last_sec = size >= 40 ? (int64_t)ms_u32(buf + 24, r->big) : -1;
    return 0;
}

static void set_record(ms_record *rec, uint64_t number, int has_time, double t, int64_t linktype, size_t start,
                       size_t len, uint64_t orig) {
    memset(rec, 0, sizeof *rec);
    rec->number = number;
    rec->time_kind = has_time ? MS_TIME_DOUBLE : MS_TIME_NONE;
    rec->time = t;
    rec->linktype = linktype;
    rec->start = start;
    rec->len = len;
    rec->orig_len = orig;
}

/* PcapReader._plausible */
static int plausible(const ms_reader *r, size_t p, int64_t last_sec, uint64_t maxlen, uint32_t div) {
    const size_t size = r->size;
    for (int depth = 0; depth < 2; depth++) {
        if (p == size && depth)
            return 1;
        if (size < 16 || p > size - 16)
            return 0;
        const uint8_t *h = r->buf + p;
        uint32_t sec = ms_u32(h, r->big), frac = ms_u32(h + 4, r->big);
        uint32_t incl = ms_u32(h + 8, r->big), orig = ms_u32(h + 12, r->big);
        if (frac >= div || incl > maxlen || orig < incl || (uint64_t)orig > 16 * maxlen)
            return 0;
        if (last_sec >= 0 && !(last_sec - RESYNC_WINDOW / 24 <= (int64_t)sec && (int64_t)sec <= last_sec + RESYNC_WINDOW))
            return 0;
        if (last_sec < 0 && !(0 < sec && (uint64_t)sec < 4102444800u))
            return 0;
        last_sec = sec;
        uint64_t next = (uint64_t)p + 16 + incl;
        if (next > size)
            return 0;
        p = (size_t)next;
    }
    return 1;
}

/* PcapReader._resync: the next plausible record header after `pos`, or -1 */
static int64_t resync(const ms_reader *r, size_t pos, int64_t last_sec, uint64_t maxlen, uint32_t div) {
    if (r->size < 15)
        return -1;
    for (size_t p = pos + 1; p < r->size - 15; p++)
        if (plausible(r, p, last_sec, maxlen, div))
            return (int64_t)p;
    return -1;
}

int ms_pcap_next(ms_reader *r, ms_record *rec) {
    const uint8_t *buf = r->buf;
    const size_t size = r->size;
    const int64_t lt = r->linktype;
    if (!r->header_ok) {
        r->done = 1;
        if (!size)
            return 0;
        ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, 0, "file ends %zu bytes into the 24-byte pcap header",
                     size);
        set_record(rec, 1, 0, 0.0, lt, 0, 0, 0);
        ms_reader_emit(r, rec);
        return 1;
    }
    const uint32_t div = r->nanosecond ? 1000000000u : 1000000u;
    const uint64_t maxlen = r->snaplen > MIN_MAX_RECORD ? r->snaplen : MIN_MAX_RECORD;
    const size_t last = size - 16; /* size >= 24 */
    for (;;) {
        size_t pos = r->pos;
        if (r->pending.n == 0 && pos <= last) { /* the fast loop of the Python reader, one record */
            const uint8_t *h = buf + pos;
            uint32_t sec = ms_u32(h, r->big), frac = ms_u32(h + 4, r->big);
            uint32_t incl = ms_u32(h + 8, r->big), orig = ms_u32(h + 12, r->big);
            uint64_t end = (uint64_t)pos + 16 + incl;
            if (!(end > size || incl > maxlen || orig != incl)) {
                set_record(rec, r->n + 1, 1, (double)sec + (double)frac / (double)div, lt, pos + 16, incl, orig);
                ms_reader_emit(r, rec);
                r->pos = (size_t)end;
                if (!(rec->number & 1023))
                    r->last_sec = sec;
                return 1;
            }
        }
        if (pos > last) {
            r->done = 1;
            if (pos < size) {
                ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                             "file ends %zu bytes into a 16-byte record header at offset %zu", size - pos, pos);
            } else if (r->pending.n == 0) {
                return 0;
            }
            set_record(rec, r->n + 1, 0, 0.0, lt, pos, 0, 0);
            ms_reader_emit(r, rec);
            return 1;
        }
        const uint8_t *h = buf + pos;
        uint32_t sec = ms_u32(h, r->big), frac = ms_u32(h + 4, r->big);
        uint32_t incl = ms_u32(h + 8, r->big), orig = ms_u32(h + 12, r->big);
        if (incl > maxlen) {
            int64_t found = resync(r, pos, r->last_sec, maxlen, div);
            if (found < 0) {
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "corrupt record header at offset %zu (length %u); no later record found, %zu bytes skipped",
                             pos, (unsigned)incl, size - pos);
                r->pos = size;
                continue;
            }
            ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                         "corrupt record header at offset %zu: %zu bytes skipped", pos, (size_t)found - pos);
            r->pos = (size_t)found;
            continue;
        }
        size_t start = pos + 16;
        uint64_t end = (uint64_t)start + incl;
        r->last_sec = sec;
        if (end > size) {
            ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                         "record at offset %zu has %zu of %u bytes: file cut short", pos, size - start, (unsigned)incl);
            end = size;
        }
        uint64_t o = orig;
        if (orig < incl)
            o = incl;
        else if (orig > incl)
            ms_notes_add(&r->pending, MS_NOTE_RECORD_SNAPPED, (int64_t)start, "%u of %u bytes captured",
                         (unsigned)incl, (unsigned)orig);
        set_record(rec, r->n + 1, 1, (double)sec + (double)frac / (double)div, lt, start, (size_t)end - start, o);
        ms_reader_emit(r, rec);
        r->pos = (size_t)end;
        return 1;
    }
}
