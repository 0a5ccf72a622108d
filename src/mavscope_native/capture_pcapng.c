/* pcapng files, as mavscope/capture/pcapng.py reads them: sections in either byte order, several
 * interfaces with their own link types and timestamp scales, EPB, SPB and obsolete packet blocks. */
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

void ms_notes_extend(ms_notes *dst, const ms_notes *src);

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

/* PcapngReader._header: a block header at p with a sane length (the block may run past the end) */
static int header(const ms_reader *r, size_t p, int big, block *out) {
    if (r->size < 12 || p > r->size - 12)
        return 0;
    const uint8_t *h = r->buf + p;
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

/* PcapngReader._block_at: a complete block at p whose trailer repeats its length */
static int block_at(const ms_reader *r, size_t p, int big, block *out) {
    if (!header(r, p, big, out))
        return 0;
    if ((uint64_t)p + out->len > r->size || ms_u32(r->buf + p + out->len - 4, out->big) != out->len)
        return 0;
    return 1;
}

static int64_t resync(const ms_reader *r, size_t p, int big) {
    if (r->size < 11)
        return -1;
    block b;
    for (size_t q = p + 1; q < r->size - 11; q++)
        if (block_at(r, q, big, &b) && known_type(b.type))
            return (int64_t)q;
    return -1;
}

static int add_interface(ms_reader *r, size_t pos, uint32_t blen) {
    if (r->nifaces == r->capifaces) {
        size_t cap = r->capifaces ? 2 * r->capifaces : 4;
        ms_iface *v = realloc(r->ifaces, cap * sizeof *v);
        if (v == NULL)
            return -1;
        r->ifaces = v;
        r->capifaces = cap;
    }
    const uint8_t *buf = r->buf;
    const int big = r->big;
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
            if (e <= 63) {
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

int ms_pcapng_init(ms_reader *r) {
    /* e = sniff_pcapng(buf[:12]) or "<" */
    r->big = r->size >= 12 && sniff(r->buf) == 1;
    return 0;
}

static void packet_record(ms_record *rec, uint64_t number, const ms_iface *ifc, int has_time, uint64_t ticks,
                          size_t start, size_t len, uint64_t orig) {
    memset(rec, 0, sizeof *rec);
    rec->number = number;
    rec->time_kind = has_time ? MS_TIME_TICKS : MS_TIME_NONE;
    rec->ticks = ticks;
    rec->units_pow2 = ifc->units_pow2;
    rec->units_exp = ifc->units_exp;
    rec->tsoffset = ifc->tsoffset;
    rec->linktype = ifc->linktype;
    rec->start = start;
    rec->len = len;
    rec->orig_len = orig;
}

/* PcapngReader._packet: the record of a packet block (possibly cut short by the end of the file), its own
 * notes in `notes`; 0 when it refers to no interface. */
static int packet(ms_reader *r, uint32_t btype, size_t pos, uint32_t blen, uint64_t number, ms_record *rec,
                  ms_notes *notes) {
    const uint8_t *buf = r->buf;
    const size_t size = r->size;
    const int big = r->big;
    int64_t caplen;
    uint64_t orig;
    size_t start;
    const ms_iface *ifc;
    int has_time = 0;
    uint64_t ticks = 0;
    if (btype == BT_SPB) {
        if (r->nifaces == 0 || pos + 12 > size)
            return 0;
        ifc = &r->ifaces[0];
        orig = ms_u32(buf + pos + 8, big);
        start = pos + 12;
        int64_t room = (int64_t)blen - 16;
        if ((int64_t)(size - start) < room)
            room = (int64_t)(size - start);
        caplen = (int64_t)orig < room ? (int64_t)orig : room;
        if (caplen < 0)
            caplen = 0;
        if (ifc->snaplen && (int64_t)ifc->snaplen < caplen)
            caplen = ifc->snaplen;
    } else {
        if (pos + 28 > size)
            return 0;
        const uint8_t *h = buf + pos + 8;
        uint32_t iface, hi, lo;
        if (btype == BT_EPB) {
            iface = ms_u32(h, big);
            hi = ms_u32(h + 4, big);
            lo = ms_u32(h + 8, big);
            caplen = ms_u32(h + 12, big);
            orig = ms_u32(h + 16, big);
        } else {
            iface = ms_u16(h, big);
            hi = ms_u32(h + 4, big);
            lo = ms_u32(h + 8, big);
            caplen = ms_u32(h + 12, big);
            orig = ms_u32(h + 16, big);
        }
        if (iface >= r->nifaces)
            return 0;
        ifc = &r->ifaces[iface];
        start = pos + 28;
        int64_t room = (int64_t)blen - 32;
        if ((int64_t)(size - start) < room)
            room = (int64_t)(size - start);
        if (caplen > room) {
            if ((uint64_t)pos + blen <= size)
                ms_notes_add(notes, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                             "packet block at offset %zu claims %lld captured bytes, holds %lld", pos,
                             (long long)caplen, (long long)room);
            caplen = room > 0 ? room : 0;
        }
        has_time = 1;
        ticks = ((uint64_t)hi << 32) | lo;
    }
    if ((int64_t)orig < caplen)
        orig = (uint64_t)caplen;
    else if ((int64_t)orig > caplen)
        ms_notes_add(notes, MS_NOTE_RECORD_SNAPPED, (int64_t)start, "%lld of %llu bytes captured", (long long)caplen,
                     (unsigned long long)orig);
    packet_record(rec, number, ifc, has_time, ticks, start, (size_t)caplen, orig);
    return 1;
}

static int final_record(ms_reader *r, ms_record *rec, size_t pos) {
    r->done = 1;
    if (r->pending.n == 0)
        return 0;
    memset(rec, 0, sizeof *rec);
    rec->number = r->n + 1;
    rec->linktype = r->nifaces ? (int64_t)r->ifaces[0].linktype : 1;
    rec->start = pos < r->size ? pos : r->size;
    ms_reader_emit(r, rec);
    return 1;
}

int ms_pcapng_next(ms_reader *r, ms_record *rec) {
    const uint8_t *buf = r->buf;
    const size_t size = r->size;
    for (;;) {
        const size_t pos = r->pos;
        if (pos >= size)
            return final_record(r, rec, pos);
        if (size - pos < 12) {
            ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos, "file ends %zu bytes into a block header",
                         size - pos);
            return final_record(r, rec, pos);
        }
        block b;
        if (!block_at(r, pos, r->big, &b)) {
            int64_t q = resync(r, pos, r->big);
            if (q >= 0) {
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "corrupt block at offset %zu: %zu bytes skipped", pos, (size_t)q - pos);
                r->pos = (size_t)q;
                continue;
            }
            block h;
            r->pos = size;
            if (header(r, pos, r->big, &h) && (uint64_t)pos + h.len > size) {
                ms_notes own;
                ms_notes_init(&own);
                int got = 0;
                if (h.type == BT_EPB || h.type == BT_OPB || h.type == BT_SPB)
                    got = packet(r, h.type, pos, h.len, r->n + 1, rec, &own);
                if (got)
                    ms_notes_extend(&r->pending, &own);
                ms_notes_add(&r->pending, MS_NOTE_RECORD_TRUNCATED, (int64_t)pos,
                             "block at offset %zu has %zu of %u bytes: file cut short", pos, size - pos, (unsigned)h.len);
                int failed = own.failed;
                ms_notes_free(&own);
                if (failed)
                    r->pending.failed = 1;
                if (got) {
                    r->done = 1;
                    ms_reader_emit(r, rec);
                    return 1;
                }
            } else {
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "corrupt block at offset %zu; no later block found, %zu bytes skipped", pos, size - pos);
            }
            return final_record(r, rec, size);
        }
        if (b.type == BT_EPB) {
            if (pos + 28 > size) {
                /* Python's struct.unpack_from raises here; the reader ends with its failure record */
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "unreadable from offset %zu on (error: unpack_from requires a buffer of at least %zu "
                             "bytes for unpacking 20 bytes at offset %zu (actual buffer size is %zu)); rest skipped",
                             pos, pos + 28, pos + 8, size);
                r->done = 1;
                r->pos = size;
                memset(rec, 0, sizeof *rec);
                rec->number = r->n + 1;
                rec->linktype = 1;
                rec->start = pos;
                ms_reader_emit(r, rec);
                return 1;
            }
            const uint8_t *h = buf + pos + 8;
            uint32_t iface = ms_u32(h, r->big);
            uint32_t caplen = ms_u32(h + 12, r->big);
            if (iface < r->nifaces && (int64_t)caplen <= (int64_t)b.len - 32) { /* the common case */
                const ms_iface *ifc = &r->ifaces[iface];
                uint64_t orig = ms_u32(h + 16, r->big);
                size_t start = pos + 28;
                if (orig < caplen)
                    orig = caplen;
                else if (orig > caplen)
                    ms_notes_add(&r->pending, MS_NOTE_RECORD_SNAPPED, (int64_t)start, "%u of %llu bytes captured",
                                 (unsigned)caplen, (unsigned long long)orig);
                uint64_t ticks = ((uint64_t)ms_u32(h + 4, r->big) << 32) | ms_u32(h + 8, r->big);
                packet_record(rec, r->n + 1, ifc, 1, ticks, start, caplen, orig);
                ms_reader_emit(r, rec);
                r->pos = pos + b.len;
                return 1;
            }
        }
        if (b.type == BT_EPB || b.type == BT_OPB || b.type == BT_SPB) {
            ms_notes own;
            ms_notes_init(&own);
            int got = packet(r, b.type, pos, b.len, r->n + 1, rec, &own);
            if (got)
                ms_notes_extend(&r->pending, &own);
            else
                ms_notes_add(&r->pending, MS_NOTE_CAPTURE_GARBAGE, (int64_t)pos,
                             "packet block at offset %zu refers to an undefined interface", pos);
            if (own.failed)
                r->pending.failed = 1;
            ms_notes_free(&own);
            r->pos = pos + b.len;
            if (got) {
                ms_reader_emit(r, rec);
                return 1;
            }
            continue;
        }
        if (b.type == BT_SHB) {
            r->big = b.big;
            r->nifaces = 0;
        } else if (b.type == BT_IDB) {
            if (add_interface(r, pos, b.len) != 0) {
                r->pending.failed = 1;
                return -1;
            }
        }
        r->pos = pos + b.len;
    }
}
