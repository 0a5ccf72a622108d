/* pcapng files, a port of mavscope/capture/pcapng.py, a window of the file at a time: sections in
 * either byte order, several interfaces with their own link types and timestamp scales, EPB, SPB and
 * obsolete packet blocks. The comments name the Python they mirror. */
#include "capture.h"

#include <stdlib.h>
#include <string.h>

#define BT_SHB 0x0A0D0D0Au
#define BT_IDB 0x00000001u
#define BT_OPB 0x00000002u
#define BT_SPB 0x00000003u
#define BT_NRB 0x00000004u
#define BT_ISB 0x00000005u
#define BT_EPB 0x00000006u
#define BT_DSB 0x0000000Au
#define BYTE_ORDER_MAGIC 0x1A2B3C4Du
#define MAX_BLOCK (16u * 1024u * 1024u)
#define CALENDAR_END 253402300800.0 /* 10000-01-01 */

static int known_type(uint32_t t) {
    switch (t) {
    case BT_SHB: case BT_IDB: case BT_OPB: case BT_SPB: case BT_NRB: case BT_ISB: case BT_EPB: case BT_DSB:
    case 0x80000001u: case 7: case 8: case 9: case 0xB: case 0xC:
        return 1;
    default:
        return 0;
    }
}

/* sniff_pcapng over 12 bytes at p: 0 little-endian, 1 big-endian, -1 not a section header */
static int sniff(const uint8_t *p) {
    if (memcmp(p, "\x0a\x0d\x0d\x0a", 4) != 0)
        return -1;
    if (ms_le32(p + 8) == BYTE_ORDER_MAGIC)
        return 0;
    if (ms_be32(p + 8) == BYTE_ORDER_MAGIC)
        return 1;
    return -1;
}

typedef struct {
    uint32_t type;
    uint32_t len;
    int big;
} block;

/* PcapngReader._header: a block header at buf[q] (file offset base + q) with a sane length; the block
 * itself may run past the end of the file or of buf */
static int header(const ms_reader *r, const uint8_t *buf, size_t blen, uint64_t base, size_t q, int big, block *out) {
    if (base + q + 12 > r->size || q + 12 > blen)
        return 0;
    const uint8_t *h = buf + q;
    if (memcmp(h, "\x0a\x0d\x0d\x0a", 4) == 0) {
        int e = sniff(h);
        if (e < 0)
            return 0;
        big = e;
    }
    uint32_t t = ms_u32(h, big), len = ms_u32(h + 4, big);
    if (len < 12 || (len & 3) || len > MAX_BLOCK || (t == BT_SHB && len < 28))
        return 0;
    out->type = t;
    out->len = len;
    out->big = big;
    return 1;
}

/* PcapngReader._block_at: a complete block at buf[q] whose trailer repeats its length (read from the
 * file when it lies past buf): 1, 0, or a negative MS_READ_* */
static int block_at(ms_reader *r, const uint8_t *buf, size_t blen, uint64_t base, size_t q, int big, block *out) {
    if (!header(r, buf, blen, base, q, big, out))
        return 0;
    if (base + q + out->len > r->size)
        return 0;
    const size_t t = q + out->len - 4;
    uint32_t trailer;
    if (t + 4 <= blen) {
        trailer = ms_u32(buf + t, out->big);
    } else {
        uint8_t tail[4];
        int64_t got = ms_read_small(r, base + t, 4, tail);
        if (got < 0)
            return (int)got;
        if (got < 4)
            return 0;
        trailer = ms_u32(tail, out->big);
    }
    return trailer == out->len;
}

/* PcapngReader._resync: the next sane block of a known type after `p` in *found (-1 if none), the file a
 * window at a time; 0, or a negative MS_READ_* */
static int resync(ms_reader *r, uint64_t p, int big, int64_t *found) {
    uint64_t q = p + 1;
    *found = -1;
    while (q + 11 < r->size) {
        int rc = ms_window_at(r, &r->aux, q, 0);
        if (rc != MS_READ_OK)
            return rc;
        uint64_t avail = r->aux.len < r->size - q ? r->aux.len : r->size - q;
        int64_t stop = (int64_t)avail - 11; /* offsets q + rel whose 12-byte header is in the window */
        for (int64_t rel = 0; rel < stop; rel++) {
            block b;
            int ok = block_at(r, r->aux.data, r->aux.len, q, (size_t)rel, big, &b);
            if (ok < 0)
                return ok;
            if (ok && known_type(b.type)) {
                *found = (int64_t)(q + (uint64_t)rel);
                return 0;
            }
        }
        q += stop > 1 ? (uint64_t)stop : 1;
    }
    return 0;
}

/* PcapngReader._interface: an Interface Description Block at buf[pos] and its timestamp options */
static int add_interface(ms_reader *r, const uint8_t *buf, size_t pos, uint32_t blen, int big) {
    if (r->nifaces == r->capifaces) {
        size_t cap = r->capifaces ? 2 * r->capifaces : 4;
        ms_iface *v = realloc(r->ifaces, cap * sizeof *v);
        if (v == NULL)
            return -1;
        r->ifaces = v;
        r->capifaces = cap;
    }
    ms_iface ifc = {1, 0, 0, 6, 0};
    if (blen >= 20) {
        ifc.linktype = ms_u16(buf + pos + 8, big);
        ifc.snaplen = ms_u32(buf + pos + 12, big);
    }
    size_t p = pos + 16, end = pos + blen - 4;
    while (p + 4 <= end) {
        uint16_t code = ms_u16(buf + p, big), length = ms_u16(buf + p + 2, big);
        if (code == 0)
            break;
        size_t v = p + 4;
        if (v + length > end)
            break;
        if (code == 9 && length >= 1) {
            uint8_t res = buf[v];
            int e = res & 0x7F;
            if (e <= 63) { /* a larger exponent cannot be represented; keep the default */
                ifc.units_pow2 = (res & 0x80) != 0;
                ifc.units_exp = e;
            }
        } else if (code == 14 && length >= 8) {
            uint64_t u = big ? ms_be64(buf + v) : ms_le64(buf + v);
            memcpy(&ifc.tsoffset, &u, sizeof u);
        }
        p = v + (((size_t)length + 3) & ~(size_t)3);
    }
    r->ifaces[r->nifaces++] = ifc;
    return 0;
}

/* The record's time, `ticks / units + tsoffset`, and its time-out-of-range note (Python's _time_note)
 * when it lies outside [0, 10000-01-01); a placeholder for the glue when C cannot compute it exactly. */
static void packet_time(ms_record *rec, const ms_iface *ifc, uint32_t iface, uint64_t ticks, uint64_t offset,
                        ms_notes *notes) {
    rec->time_kind = MS_TIME_TICKS;
    rec->ticks = ticks;
    rec->units_pow2 = ifc->units_pow2;
    rec->units_exp = ifc->units_exp;
    rec->tsoffset = ifc->tsoffset;
    double t;
    if (ms_record_time(rec, &t) < 0) {
        ms_notes_add(notes, MS_NOTE_TIME_CHECK, (int64_t)offset, "%u", (unsigned)iface);
        return;
    }
    if (0.0 <= t && t < CALENDAR_END)
        return;
    unsigned long long units = 1;
    for (int i = 0; i < ifc->units_exp; i++)
        units *= ifc->units_pow2 ? 2u : 10u;
    ms_notes_add(notes, MS_NOTE_TIME_OUT_OF_RANGE, (int64_t)offset,
                 "packet time %.6g s since 1970 (interface %u: if_tsoffset %lld s, %llu ticks/s)", t, (unsigned)iface,
                 (long long)ifc->tsoffset, units);
}

/* PcapngReader._packet: the record of a packet block at buf[pos] (file offset base + pos; possibly cut
 * short by the end of the file), with its own notes in `notes`; 0 when it refers to no interface. `buf`
 * holds the block, or the file's bytes to its end. */
static int packet(ms_reader *r, const uint8_t *buf, uint64_t base, size_t pos, uint32_t btype, uint32_t blen,
                  int big, ms_record *rec, ms_notes *notes) {
    const int64_t size = (int64_t)r->size - (int64_t)base; /* where the file ends, as an index into buf */
    const int64_t ipos = (int64_t)pos;
    int64_t caplen, orig, start;
    const ms_iface *ifc;
    if (btype == BT_SPB) {
        if (r->nifaces == 0 || ipos + 12 > size)
            return 0;
        ifc = &r->ifaces[0];
        orig = ms_u32(buf + pos + 8, big);
        start = ipos + 12;
        int64_t room = (int64_t)blen - 16 < size - start ? (int64_t)blen - 16 : size - start;
        caplen = orig < room ? orig : room;
        if (caplen < 0)
            caplen = 0;
        if (ifc->snaplen && (int64_t)ifc->snaplen < caplen)
            caplen = ifc->snaplen;
        ms_record_set(rec, ifc->linktype, buf + start, (size_t)caplen, base + (uint64_t)start, 0);
    } else {
        if (ipos + 28 > size)
            return 0;
        const uint8_t *h = buf + pos + 8;
        uint32_t iface = btype == BT_EPB ? ms_u32(h, big) : ms_u16(h, big);
        uint32_t hi = ms_u32(h + 4, big), lo = ms_u32(h + 8, big);
        caplen = ms_u32(h + 12, big);
        orig = ms_u32(h + 16, big);
        if (iface >= r->nifaces)
            return 0;
        ifc = &r->ifaces[iface];
        start = ipos + 28;
        int64_t room = (int64_t)blen - 32 < size - start ? (int64_t)blen - 32 : size - start;
        if (caplen > room) {
            if (ipos + (int64_t)blen <= size)
                ms_notes_add(notes, MS_NOTE_RECORD_TRUNCATED, (int64_t)(base + pos),
                             "packet block at offset %llu claims %lld captured bytes, holds %lld",
                             (unsigned long long)(base + pos), (long long)caplen, (long long)room);
            caplen = room > 0 ? room : 0;
        }
        ms_record_set(rec, ifc->linktype, buf + start, (size_t)caplen, base + (uint64_t)start, 0);
        packet_time(rec, ifc, iface, ((uint64_t)hi << 32) | lo, base + pos, notes);
    }
    if (orig < caplen)
        orig = caplen;
    else if (orig > caplen)
        ms_notes_add(notes, MS_NOTE_RECORD_SNAPPED, (int64_t)(base + (uint64_t)start), "%lld of %lld bytes captured",
                     (long long)caplen, (long long)orig);
    rec->orig_len = (uint64_t)orig;
    return 1;
}

/* The end: the shrink note, and a record for whatever notes are pending */
static int final_record(ms_reader *r, ms_record *rec, uint64_t pos) {
    r->done = 1;
    ms_shrink_notes(r, &r->pending);
    r->position = r->size;
    if (r->pending.n == 0)
        return 0;
    ms_record_set(rec, r->nifaces ? (int64_t)r->ifaces[0].linktype : 1, NULL, 0, pos < r->size ? pos : r->size, 0);
    ms_reader_emit(r, rec);
    return 1;
}

/* A packet block's record: the pending notes, then its own (and `extra`, the cut note, when given) */
static int emit_packet(ms_reader *r, ms_record *rec, ms_notes *own) {
    ms_notes_extend(&r->pending, own);
    ms_notes_free(own);
    ms_reader_emit(r, rec);
    return 1;
}

#define FAIL(rc) return ms_reader_fail(r, rec, r->pos, (rc), 1)

/* PcapngReader._records, one record per call */
int ms_pcapng_next(ms_reader *r, ms_record *rec) {
    if (!r->started) {
        r->started = 1;
        int rc = ms_window_at(r, &r->win, 0, 0);
        if (rc != MS_READ_OK)
            FAIL(rc);
        r->big = r->win.len >= 12 && sniff(r->win.data) == 1; /* sniff_pcapng(buf[:12]) or "<" */
    }
    for (;;) {
        const uint64_t pos = r->pos;
        uint64_t size = r->size;
        if (pos >= size)
            return final_record(r, rec, pos);
        const uint64_t base = r->win.base;
        const uint8_t *buf = r->win.data;
        const size_t blen = r->win.len;
        size_t rel = (size_t)(pos - base);
        if (pos >= base && rel + 28 <= blen) {
            /* the common case: an Enhanced Packet Block in the window, of a known interface */
            const uint8_t *h = buf + rel;
            const int big = r->big;
            uint32_t btype = ms_u32(h, big), bl = ms_u32(h + 4, big), iface = ms_u32(h + 8, big);
            uint32_t caplen = ms_u32(h + 20, big);
            if (btype == BT_EPB && iface < r->nifaces && (int64_t)caplen <= (int64_t)bl - 32 && bl <= MAX_BLOCK &&
                !(bl & 3) && rel + bl <= blen && ms_u32(h + bl - 4, big) == bl) {
                const ms_iface *ifc = &r->ifaces[iface];
                uint64_t orig = ms_u32(h + 24, big);
                const size_t start = rel + 28;
                if (orig < caplen)
                    orig = caplen;
                else if (orig > caplen)
                    ms_notes_add(&r->pending, MS_NOTE_RECORD_SNAPPED, (int64_t)(base + start),
                                 "%u of %llu bytes captured", (unsigned)caplen, (unsigned long long)orig);
                ms_record_set(rec, ifc->linktype, buf + start, caplen, base + start, orig);
                uint64_t ticks = ((uint64_t)ms_u32(h + 12, big) << 32) | ms_u32(h + 16, big);
                packet_time(rec, ifc, iface, ticks, base + rel, &r->pending);
                ms_reader_emit(r, rec);
                r->pos = pos + bl;
                if (!(rec->number & 1023))
                    r->position = r->pos;
                return 1;
            }
        }
        r->position = pos;
        const uint64_t have = base + blen; /* the window holds the file's bytes up to here */
        if (pos + 12 > size) {
            ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos, "file ends %llu bytes into a block header",
                         (unsigned long long)(size - pos));
            return final_record(r, rec, pos);
        }
        if (pos + 12 > have) {
            int rc = ms_window_at(r, &r->win, pos, 0);
            if (rc != MS_READ_OK)
                FAIL(rc);
            continue;
        }
        block head;
        const int have_head = header(r, buf, blen, base, rel, r->big, &head);
        if (have_head) {
            const size_t need = head.len > 28 ? head.len : 28; /* a short packet block is read as one */
            if (pos + need > have && have < size && pos + head.len <= size) {
                int rc = ms_window_at(r, &r->win, pos, need); /* read the whole block */
                if (rc != MS_READ_OK)
                    FAIL(rc);
                continue;
            }
        }
        block b;
        int ok = block_at(r, buf, blen, base, rel, r->big, &b);
        if (ok < 0)
            FAIL(ok);
        if (!ok) {
            int64_t q;
            int rc = resync(r, pos, r->big, &q);
            if (rc != 0)
                FAIL(rc);
            size = r->size;
            if (q >= 0) {
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "corrupt block at offset %llu: %llu bytes skipped", (unsigned long long)pos,
                             (unsigned long long)((uint64_t)q - pos));
                r->pos = (uint64_t)q;
                continue;
            }
            if (have_head && pos + head.len > size) {
                /* a sane header whose block runs past the end, and nothing after: the file was cut short */
                ms_notes cut;
                ms_notes_init(&cut);
                ms_notes_add(&cut, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                             "block at offset %llu has %lld of %u bytes: file cut short", (unsigned long long)pos,
                             (long long)size - (long long)pos, (unsigned)head.len);
                int got = 0;
                ms_notes own;
                ms_notes_init(&own);
                if (head.type == BT_EPB || head.type == BT_OPB || head.type == BT_SPB) {
                    rc = ms_window_at(r, &r->win, pos, (size_t)(size - pos));
                    if (rc != MS_READ_OK) {
                        ms_notes_free(&cut);
                        ms_notes_free(&own);
                        FAIL(rc);
                    }
                    got = packet(r, r->win.data, pos, 0, head.type, head.len, r->big, rec, &own);
                }
                r->pos = r->size;
                if (got) {
                    r->position = r->size;
                    ms_notes_extend(&own, &cut);
                    ms_notes_free(&cut);
                    return emit_packet(r, rec, &own); /* the shrink note (if any) comes on a record of its own */
                }
                ms_notes_free(&own);
                ms_notes_extend(&r->pending, &cut);
                ms_notes_free(&cut);
            } else {
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "corrupt block at offset %llu; no later block found, %lld bytes skipped",
                             (unsigned long long)pos, (long long)size - (long long)pos);
                r->pos = size;
            }
            return final_record(r, rec, r->pos);
        }
        if (b.type == BT_EPB || b.type == BT_OPB || b.type == BT_SPB) {
            ms_notes own;
            ms_notes_init(&own);
            int got = packet(r, buf, base, rel, b.type, b.len, r->big, rec, &own);
            r->pos = pos + b.len;
            if (got)
                return emit_packet(r, rec, &own);
            ms_notes_free(&own);
            ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                         "packet block at offset %llu refers to an undefined interface", (unsigned long long)pos);
            continue;
        }
        if (b.type == BT_SHB) {
            r->big = b.big;
            r->nifaces = 0;
        } else if (b.type == BT_IDB) {
            if (add_interface(r, buf, rel, b.len, r->big) != 0) {
                r->pending.failed = 1;
                return -1;
            }
        }
        r->pos = pos + b.len;
    }
}
