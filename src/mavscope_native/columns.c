#include "columns.h"

#include <stdlib.h>
#include <string.h>

#include "mavlink.h"

const char *const MS_COL_NAMES[MS_NCOLS] = {
    [MS_COL_RECORD] = "record", [MS_COL_INDEX] = "index", [MS_COL_TIME] = "time", [MS_COL_TIME_OK] = "time_ok",
    [MS_COL_TRANSPORT] = "transport", [MS_COL_SRC] = "src", [MS_COL_DST] = "dst", [MS_COL_VERSION] = "version",
    [MS_COL_LEN] = "len", [MS_COL_IFLAGS] = "incompat_flags", [MS_COL_CFLAGS] = "compat_flags",
    [MS_COL_SEQ] = "seq", [MS_COL_SYSID] = "sysid", [MS_COL_COMPID] = "compid", [MS_COL_MSGID] = "msgid",
    [MS_COL_MESSAGE] = "message", [MS_COL_CRC] = "crc", [MS_COL_SIG_LINK] = "signature_link_id",
    [MS_COL_SIG_TIME] = "signature_timestamp", [MS_COL_SIG_VALUE] = "signature_value",
    [MS_COL_OFFSET] = "offset", [MS_COL_PAYLOAD_AT] = "payload_at", [MS_COL_PAYLOAD] = "payload",
    [MS_COL_RAW_AT] = "raw_at", [MS_COL_RAW] = "raw", [MS_COL_SIZE] = "size", [MS_COL_NOTE] = "note",
};

const uint8_t MS_COL_WIDTH[MS_NCOLS] = {
    [MS_COL_RECORD] = 8, [MS_COL_INDEX] = 4, [MS_COL_TIME] = 8, [MS_COL_TIME_OK] = 1, [MS_COL_TRANSPORT] = 1,
    [MS_COL_SRC] = 4, [MS_COL_DST] = 4, [MS_COL_VERSION] = 1, [MS_COL_LEN] = 1, [MS_COL_IFLAGS] = 1,
    [MS_COL_CFLAGS] = 1, [MS_COL_SEQ] = 1, [MS_COL_SYSID] = 1, [MS_COL_COMPID] = 1, [MS_COL_MSGID] = 4,
    [MS_COL_MESSAGE] = 4, [MS_COL_CRC] = 2, [MS_COL_SIG_LINK] = 1, [MS_COL_SIG_TIME] = 8, [MS_COL_SIG_VALUE] = 6,
    [MS_COL_OFFSET] = 8, [MS_COL_SIZE] = 2, [MS_COL_NOTE] = 1,
};

int ms_cols_init(ms_cols *c, const ms_table *table, uint32_t limit) {
    memset(c, 0, sizeof *c);
    c->table = table;
    c->limit = limit < 1 ? 1 : (limit > MS_COLS_MAX_FRAMES ? MS_COLS_MAX_FRAMES : limit);
    for (int k = 0; k < MS_NCOLS; k++)
        ms_buf_init(&c->col[k]);
    const size_t nm = table->count ? table->count : 1;
    c->msgs = calloc(nm, sizeof *c->msgs);
    c->touched = calloc(nm, sizeof *c->touched);
    if (c->msgs == NULL || c->touched == NULL) {
        ms_cols_free(c);
        return -1;
    }
    for (size_t i = 0; i < nm; i++) {
        ms_buf_init(&c->msgs[i].rows);
        ms_buf_init(&c->msgs[i].frame);
    }
    return 0;
}

void ms_cols_free(ms_cols *c) {
    for (int k = 0; k < MS_NCOLS; k++)
        ms_buf_free(&c->col[k]);
    if (c->msgs != NULL) {
        for (size_t i = 0; i < (c->table->count ? c->table->count : 1); i++) {
            ms_buf_free(&c->msgs[i].rows);
            ms_buf_free(&c->msgs[i].frame);
        }
    }
    free(c->msgs);
    free(c->touched);
    free(c->ends);
    free(c->slots);
    memset(c, 0, sizeof *c);
}

/* Put `e` (already in ends[id]) into the map of `nslots` slots. */
static void endpoint_slot(uint32_t *slots, uint32_t nslots, const ms_endpoint *e, uint32_t id) {
    uint32_t j = ms_endpoint_hash(e) & (nslots - 1);
    while (slots[j] != 0)
        j = (j + 1) & (nslots - 1);
    slots[j] = id + 1;
}

static int64_t endpoint_lookup(ms_cols *c, const ms_endpoint *ep);

/* The id of an endpoint (a new one when first seen), or -1 when memory runs out. */
static int64_t endpoint_id(ms_cols *c, int v6, const uint8_t *addr, uint16_t port) {
    const unsigned r = (unsigned)(port ^ (port >> 3) ^ addr[v6 ? 15 : 3]) & 7u;
    const ms_endpoint *hit = &c->recent[r];
    if (c->recent_ok[r] && hit->port == port && hit->v6 == (uint8_t)v6 && memcmp(hit->addr, addr, v6 ? 16 : 4) == 0)
        return c->recent_id[r]; /* an IPv4 entry's other 12 bytes are zeros, as `e` would hold them */
    ms_endpoint e;
    memset(&e, 0, sizeof e);
    e.v6 = (uint8_t)v6;
    memcpy(e.addr, addr, v6 ? 16 : 4);
    e.port = port;
    const int64_t id = endpoint_lookup(c, &e);
    if (id >= 0) {
        memcpy(&c->recent[r], &e, sizeof e);
        c->recent_id[r] = (uint32_t)id;
        c->recent_ok[r] = 1;
    }
    return id;
}

/* The id of endpoint `e` (a new one when first seen), or -1 when memory runs out. */
static int64_t endpoint_lookup(ms_cols *c, const ms_endpoint *ep) {
    const ms_endpoint e = *ep;
    if (c->nslots != 0) {
        uint32_t j = ms_endpoint_hash(&e) & (c->nslots - 1);
        while (c->slots[j] != 0) {
            const ms_endpoint *o = &c->ends[c->slots[j] - 1];
            if (memcmp(o, &e, sizeof e) == 0)
                return (int64_t)c->slots[j] - 1;
            j = (j + 1) & (c->nslots - 1);
        }
    }
    if (c->nends == UINT32_MAX - 1)
        return -1;
    if (c->nends >= c->capends) {
        uint32_t cap = c->capends ? 2 * c->capends : 64;
        ms_endpoint *p = realloc(c->ends, (size_t)cap * sizeof *p);
        if (p == NULL)
            return -1;
        c->ends = p;
        c->capends = cap;
    }
    if (2 * ((size_t)c->nends + 1) > c->nslots) { /* keep the map at most half full */
        uint32_t ns = c->nslots ? 2 * c->nslots : 128;
        uint32_t *s = calloc(ns, sizeof *s);
        if (s == NULL)
            return -1;
        for (uint32_t i = 0; i < c->nends; i++)
            endpoint_slot(s, ns, &c->ends[i], i);
        free(c->slots);
        c->slots = s;
        c->nslots = ns;
    }
    c->ends[c->nends] = e;
    endpoint_slot(c->slots, c->nslots, &e, c->nends);
    return c->nends++;
}

static inline void put(ms_cols *c, int k, const void *v) {
    ms_buf_put(&c->col[k], v, MS_COL_WIDTH[k]);
}

static inline void put_u8(ms_cols *c, int k, unsigned v) {
    ms_buf_byte(&c->col[k], (char)(uint8_t)v);
}

static void put_i32(ms_cols *c, int k, int32_t v) {
    ms_buf_put(&c->col[k], &v, 4);
}

/* One message row: the payload zero-extended to the message's length, and its frame's position. */
static int message_row(ms_cols *c, const ms_message *m, const uint8_t *payload, size_t len) {
    const size_t k = (size_t)(m - c->table->messages);
    ms_msg_rows *r = &c->msgs[k];
    char *p = ms_buf_room(&r->rows, m->length);
    if (p == NULL)
        return -1;
    const size_t take = len < m->length ? len : m->length;
    memcpy(p, payload, take);
    memset(p + take, 0, m->length - take);
    r->rows.len += m->length;
    uint32_t at = c->n;
    ms_buf_put(&r->frame, &at, 4);
    if (r->frame.failed)
        return -1;
    r->n++;
    if (!r->listed) {
        r->listed = 1;
        c->touched[c->ntouched++] = (uint32_t)k;
    }
    return 0;
}

/* The frames of one record (`raw` 0: record `number`, index i + 1) or of a raw stream's stretch (`raw` 1: record
 * `number + i`, index 1), all with the same time, transport and endpoints. */
static int put_frames(ms_cols *c, const uint8_t *d, uint64_t base, const uint32_t *frames, const uint8_t *notes,
                      size_t count, int64_t number, int raw, int has_time, double t, uint8_t transport, int32_t src,
                      int32_t dst) {
    const int full = !c->index_only;
    if (full && c->n == 0 && c->col[MS_COL_PAYLOAD_AT].len == 0) {
        put_i32(c, MS_COL_PAYLOAD_AT, 0);
        put_i32(c, MS_COL_RAW_AT, 0);
    }
    const uint8_t time_ok = has_time ? 1 : 0;
    const double time = has_time ? t : 0.0;
    for (size_t i = 0; i < count; i++) {
        if (c->n >= MS_COLS_MAX_FRAMES) {
            c->failed = 1;
            return -1;
        }
        const uint8_t *f = d + frames[2 * i];
        const size_t size = frames[2 * i + 1];
        const int v2 = f[0] == MS_STX_V2;
        const size_t hlen = v2 ? MS_HEADER_V2 : MS_HEADER_V1;
        const size_t len = f[1];
        const uint32_t msgid = v2 ? (uint32_t)f[7] | ((uint32_t)f[8] << 8) | ((uint32_t)f[9] << 16) : f[5];
        const ms_message *m = ms_table_get(c->table, msgid); /* the walk checked it */
        if (m == NULL) {
            c->failed = 1;
            return -1;
        }
        const int32_t index = raw ? 1 : (int32_t)(i + 1);
        const int64_t record = raw ? number + (int64_t)i : number;
        const int64_t offset = (int64_t)(base + frames[2 * i]);
        const uint16_t fsize = (uint16_t)size;
        put(c, MS_COL_RECORD, &record);
        put(c, MS_COL_INDEX, &index);
        put(c, MS_COL_TIME, &time);
        put_u8(c, MS_COL_TIME_OK, time_ok);
        put_u8(c, MS_COL_TRANSPORT, transport);
        put(c, MS_COL_SRC, &src);
        put(c, MS_COL_DST, &dst);
        put_u8(c, MS_COL_IFLAGS, v2 ? f[2] : 0);
        put_u8(c, MS_COL_SEQ, f[v2 ? 4 : 2]);
        put_u8(c, MS_COL_SYSID, f[v2 ? 5 : 3]);
        put_u8(c, MS_COL_COMPID, f[v2 ? 6 : 4]);
        put(c, MS_COL_MSGID, &msgid);
        put(c, MS_COL_OFFSET, &offset);
        put(c, MS_COL_SIZE, &fsize);
        const uint8_t fnote = notes != NULL ? notes[i] : 0;
        if (!full) {
            c->n++;
            continue;
        }
        put_u8(c, MS_COL_NOTE, fnote);
        const int32_t message = (int32_t)(m - c->table->messages);
        const uint16_t crc = (uint16_t)(f[hlen + len] | (f[hlen + len + 1] << 8));
        const int is_signed = v2 && (f[2] & 1);
        uint8_t link = 0, value[6] = {0};
        int64_t stamp = 0;
        if (is_signed) {
            const uint8_t *s = f + size - MS_SIGNATURE_LEN;
            link = s[0];
            for (int b = 6; b >= 1; b--)
                stamp = (stamp << 8) | s[b];
            memcpy(value, s + 7, 6);
        }
        put_u8(c, MS_COL_VERSION, v2 ? 2 : 1);
        put_u8(c, MS_COL_LEN, (unsigned)len);
        put_u8(c, MS_COL_CFLAGS, v2 ? f[3] : 0);
        put(c, MS_COL_MESSAGE, &message);
        put(c, MS_COL_CRC, &crc);
        put_u8(c, MS_COL_SIG_LINK, link);
        put(c, MS_COL_SIG_TIME, &stamp);
        put(c, MS_COL_SIG_VALUE, value);
        ms_buf_put(&c->col[MS_COL_PAYLOAD], f + hlen, len);
        put_i32(c, MS_COL_PAYLOAD_AT, (int32_t)c->col[MS_COL_PAYLOAD].len);
        ms_buf_put(&c->col[MS_COL_RAW], f, size);
        put_i32(c, MS_COL_RAW_AT, (int32_t)c->col[MS_COL_RAW].len);
        if (!(fnote & MS_NOTE_BAD_CRC) && message_row(c, m, f + hlen, len) != 0) {
            c->failed = 1;
            return -1;
        }
        c->n++;
    }
    for (int k = 0; k < MS_NCOLS; k++) {
        if (c->col[k].failed) {
            c->failed = 1;
            return -1;
        }
    }
    return 0;
}

int ms_cols_record(ms_cols *c, const ms_record *rec, const uint8_t *d, const uint32_t *frames, const uint8_t *notes,
                   size_t count, int has_time, double t, const ms_udp *udp) {
    if (c->failed)
        return -1;
    int32_t src = -1, dst = -1;
    if (udp != NULL) {
        int64_t s = endpoint_id(c, udp->v6, udp->src, udp->sport);
        int64_t e = s < 0 ? -1 : endpoint_id(c, udp->v6, udp->dst, udp->dport);
        if (s < 0 || e < 0 || s > INT32_MAX || e > INT32_MAX) {
            c->failed = 1;
            return -1;
        }
        src = (int32_t)s;
        dst = (int32_t)e;
    }
    return put_frames(c, d, rec->offset + (uint64_t)(d - rec->data), frames, notes, count, (int64_t)rec->number, 0,
                      has_time, t, udp != NULL ? MS_TRANSPORT_UDP : MS_TRANSPORT_TLOG, src, dst);
}

int ms_cols_raw(ms_cols *c, const uint8_t *d, uint64_t base, const uint32_t *frames, const uint8_t *notes,
                size_t count, uint64_t first) {
    if (c->failed)
        return -1;
    if (first > (uint64_t)INT64_MAX - count) {
        c->failed = 1;
        return -1;
    }
    return put_frames(c, d, base, frames, notes, count, (int64_t)first, 1, 0, 0.0, MS_TRANSPORT_RAW, -1, -1);
}

void ms_cols_restart(ms_cols *c) {
    for (int k = 0; k < MS_NCOLS; k++)
        c->col[k].len = 0;
    for (uint32_t i = 0; i < c->ntouched; i++) {
        ms_msg_rows *r = &c->msgs[c->touched[i]];
        r->rows.len = 0;
        r->frame.len = 0;
        r->n = 0;
        r->listed = 0;
    }
    c->ntouched = 0;
    c->n = 0;
    c->reset = 0;
    if (c->nends > MS_COLS_ENDPOINTS) {
        memset(c->slots, 0, (size_t)c->nslots * sizeof *c->slots);
        memset(c->recent_ok, 0, sizeof c->recent_ok);
        c->nends = 0;
        c->reset = 1;
    }
    c->first_new = c->nends;
}
