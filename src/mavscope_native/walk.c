#include "walk.h"

#include <stdlib.h>
#include <string.h>

#include "decode.h"
#include "fmt.h"
#include "mavlink.h"
#include "netlayers.h"

#define SETUP_SIGNING 256
#define KEY_EXCHANGE 65100
#define RADIO_STATUS 109 /* a radio adds it unsigned to a signed stream: no note (security/stage.py) */
#define SEEN_MAX 65536 /* endpoints remembered as reported; past that the memory starts over */

int ms_walker_init(ms_walker *w, ms_source src, uint64_t size, int kind, const ms_table *table) {
    memset(w, 0, sizeof *w);
    ms_reader_init(&w->reader, src, size, kind);
    w->table = table;
    w->sign_mode = MS_SIGNED_HANDBACK;
    w->py_index = -1;
    w->raw_held = -1;
    w->carry_ok = 1;
    return 0;
}

void ms_walker_free(ms_walker *w) {
    ms_reader_free(&w->reader);
    free(w->waiting);
    free(w->new_signers);
    free(w->new_endpoints);
    free(w->seen);
    free(w->seen_used);
    free(w->frames);
    free(w->fnote);
    free(w->fbad);
    free((void *)w->ports);
    for (int i = 0; i < MS_NOTE_TPLS; i++)
        for (int j = 0; j < 4; j++)
            free(w->note_tpl[i][j]);
    free(w->tentative);
    free(w->sig_keys);
    free(w->pending);
    free(w->carry);
    memset(w, 0, sizeof *w);
}

static int grow(void **v, size_t *cap, size_t need, size_t item) {
    if (need <= *cap)
        return 0;
    size_t c = *cap ? *cap : 16;
    while (c < need)
        c *= 2;
    void *p = realloc(*v, c * item);
    if (p == NULL)
        return -1;
    *v = p;
    *cap = c;
    return 0;
}

int ms_walker_waiting_room(ms_walker *w, size_t n) {
    return grow((void **)&w->waiting, &w->cap_waiting, n, sizeof *w->waiting);
}

/* `e` among the endpoints already reported: 1 if so, 0 if not. */
static int seen_has(const ms_walker *w, const ms_endpoint *e) {
    if (w->have_last_noted && memcmp(&w->last_noted, e, sizeof *e) == 0)
        return 1;
    if (w->capseen == 0)
        return 0;
    size_t j = ms_endpoint_hash(e) & (w->capseen - 1);
    while (w->seen_used[j]) {
        if (memcmp(&w->seen[j], e, sizeof *e) == 0)
            return 1;
        j = (j + 1) & (w->capseen - 1);
    }
    return 0;
}

/* Put `e` among the endpoints already reported: 1 if it was not there, 0 if it was, -1 out of memory. */
static int seen_put(ms_walker *w, const ms_endpoint *e) {
    if (w->capseen == 0 || w->nseen * 2 >= w->capseen) {
        if (w->capseen >= 2 * SEEN_MAX) {
            memset(w->seen_used, 0, w->capseen); /* start over: re-adding to a Python set is harmless */
            w->nseen = 0;
        } else {
            size_t cap = w->capseen ? 2 * w->capseen : 256;
            ms_endpoint *seen = calloc(cap, sizeof *seen);
            uint8_t *used = calloc(cap, 1);
            if (seen == NULL || used == NULL) {
                free(seen);
                free(used);
                return -1;
            }
            for (size_t i = 0; i < w->capseen; i++) {
                if (!w->seen_used[i])
                    continue;
                size_t j = ms_endpoint_hash(&w->seen[i]) & (cap - 1);
                while (used[j])
                    j = (j + 1) & (cap - 1);
                seen[j] = w->seen[i];
                used[j] = 1;
            }
            free(w->seen);
            free(w->seen_used);
            w->seen = seen;
            w->seen_used = used;
            w->capseen = cap;
        }
    }
    size_t j = ms_endpoint_hash(e) & (w->capseen - 1);
    while (w->seen_used[j]) {
        if (memcmp(&w->seen[j], e, sizeof *e) == 0)
            return 0;
        j = (j + 1) & (w->capseen - 1);
    }
    w->seen[j] = *e;
    w->seen_used[j] = 1;
    w->nseen++;
    return 1;
}

int ms_walker_remember_endpoint(ms_walker *w, const ms_endpoint *e) {
    return seen_put(w, e) < 0 ? -1 : 0;
}

/* Record `e` as a source of valid MAVLink unless it was reported already. */
static int note_endpoint(ms_walker *w, const ms_endpoint *e) {
    if (w->have_last_noted && memcmp(&w->last_noted, e, sizeof *e) == 0)
        return 0;
    w->last_noted = *e;
    w->have_last_noted = 1;
    if (grow((void **)&w->new_endpoints, &w->cap_new_endpoints, w->n_new_endpoints + 1, sizeof *e) != 0)
        return -1;
    int r = seen_put(w, e);
    if (r < 0)
        return -1;
    if (r > 0)
        w->new_endpoints[w->n_new_endpoints++] = *e;
    return 0;
}

/* The "ip:port" text of an endpoint, from a two-entry cache (a flow and its reverse). */
static const char *endpoint_text(ms_walker *w, int v6, const uint8_t *addr, uint16_t port, int *len) {
    ms_endpoint e;
    memset(&e, 0, sizeof e);
    e.v6 = (uint8_t)v6;
    memcpy(e.addr, addr, v6 ? 16 : 4);
    e.port = port;
    for (int i = 0; i < 2; i++) {
        if (w->text_len[i] && memcmp(&w->text_key[i], &e, sizeof e) == 0) {
            *len = w->text_len[i];
            return w->text[i];
        }
    }
    /* replace the older entry: keep [0] the most recent */
    w->text_key[1] = w->text_key[0];
    memcpy(w->text[1], w->text[0], sizeof w->text[0]);
    w->text_len[1] = w->text_len[0];
    w->text_key[0] = e;
    w->text_len[0] = ms_fmt_endpoint(v6, addr, port, w->text[0]);
    *len = w->text_len[0];
    return w->text[0];
}

enum { CLEAN = 1, NOT_CLEAN = 0, NOMEM = -1 };

/* MS_SIGNED_VERIFY: whether the signed frame f[0..size) (frame `k` of the record) is the next of a known
 * stream under the key that verified it last: the stream's last timestamp (or the one an earlier frame
 * of this record would set) is older and that key's MAC matches: the Python verifier's `valid` with
 * reason `mac-ok` (the hint is the key it tries first). Everything else (a new stream, a replay, a MAC
 * of another key or of none) is the Python verifier's: NOT_CLEAN. */
static int verify_signed(ms_walker *w, const uint8_t *f, size_t size, size_t k) {
    const ms_signing *s = w->signing;
    if (s == NULL)
        return NOT_CLEAN;
    const uint8_t *sig = f + size - MS_SIGNATURE_LEN;
    const uint32_t stream = ms_sign_stream(f[5], f[6], sig[0]);
    const ms_sign_entry *e = ms_signing_find(s, stream);
    if (e == NULL || e->key >= s->nkeys || s->keys[e->key].name == NULL)
        return NOT_CLEAN;
    uint64_t last = e->last;
    for (size_t i = w->n_pending; i-- > 0;) {
        if (w->pending[i].stream == stream) {
            last = w->pending[i].last;
            break;
        }
    }
    uint64_t ts = 0;
    for (int i = 6; i >= 1; i--)
        ts = (ts << 8) | sig[i];
    if (ts <= last || !(ms_signing_mac_ok(&s->keys[e->key], f, size - 6, sig + 7) || w->fuzz_any_mac))
        return NOT_CLEAN;
    if (grow((void **)&w->pending, &w->cap_pending, w->n_pending + 1, sizeof *w->pending) != 0 ||
        grow((void **)&w->sig_keys, &w->cap_sig_keys, k + 1, sizeof *w->sig_keys) != 0)
        return NOMEM;
    w->pending[w->n_pending].stream = stream;
    w->pending[w->n_pending].key = e->key;
    w->pending[w->n_pending].last = ts;
    w->n_pending++;
    w->sig_keys[k] = e->key;
    return CLEAN;
}

/* Whether the walk takes a frame with note template `tpl`'s note (MS_TPL_*) rather than handing its record
 * back: the JSON Lines and summary walks write it (their templates are set), the column mode with `notes`
 * gives its code (columns.h MS_NOTE_*). */
static int takes_notes(const ms_walker *w, int tpl) {
    if (w->cols != NULL)
        return w->cols->notes;
    return w->note_tpl[tpl][0] != NULL;
}

/* Whether the frame at d[pos..n) is one the native path writes (frame `k` of the record or stretch; `*t` the
 * senders it would add so far, in w->tentative): CLEAN with its (position, size) in w->frames[k], its note in
 * w->fnote[k] and its CRC verdict in w->fbad[k]; NOT_CLEAN; or NOMEM. A frame with a bad CRC is taken only
 * after a frame with a good one: the caller checks that a CRC-valid frame follows it (or the data ends). */
static int clean_frame(ms_walker *w, const uint8_t *d, size_t pos, size_t n, size_t k, size_t *t) {
    const size_t left = n - pos;
    const uint8_t *f = d + pos;
    const ms_message *m;
    size_t size, hlen, len;
    unsigned sender;
    int is_signed = 0;
    if (f[0] == MS_STX_V2) {
        if (left < 12)
            return NOT_CLEAN;
        len = f[1];
        const unsigned iflags = f[2];
        if (iflags & ~1u)
            return NOT_CLEAN; /* encrypted or unknown flags: notes, Python */
        is_signed = (int)iflags;
        hlen = MS_HEADER_V2;
        size = 12 + len + (is_signed ? MS_SIGNATURE_LEN : 0);
        if (size > left)
            return NOT_CLEAN;
        const uint32_t msgid = (uint32_t)f[7] | ((uint32_t)f[8] << 8) | ((uint32_t)f[9] << 16);
        m = ms_table_get(w->table, msgid);
        if (m == NULL || len > m->length)
            return NOT_CLEAN;
        sender = ((unsigned)f[5] << 8) | f[6];
    } else if (f[0] == MS_STX_V1) {
        if (left < 8)
            return NOT_CLEAN;
        len = f[1];
        hlen = MS_HEADER_V1;
        size = 8 + len;
        if (size > left)
            return NOT_CLEAN;
        m = ms_table_get(w->table, f[5]);
        if (m == NULL || len != m->base_length)
            return NOT_CLEAN;
        sender = ((unsigned)f[3] << 8) | f[4];
    } else {
        return NOT_CLEAN;
    }
    if (m->python_only || m->msgid == SETUP_SIGNING || m->msgid == KEY_EXCHANGE)
        return NOT_CLEAN;
    if (m->has_char && ms_char_tail(m, f + hlen, len))
        return NOT_CLEAN; /* bytes after a string's NUL: the char-after-nul note, Python */
    uint16_t crc = ms_crc16(f + 1, hlen - 1 + len, 0xFFFF);
    crc = ms_crc16(&m->crc_extra, 1, crc);
    uint8_t bad = 0;
    if (crc != ms_le16(f + hlen + len) && !w->fuzz_any_crc) {
        /* a frame with a bad CRC, as the framer takes one (framing.py: it ends where the data ends or a
         * CRC-valid frame begins, checked at the next frame), unsigned (a receiver reads a bad frame's
         * signature afresh) and not ending in an STX byte (mavlink_parse_char starts a frame there:
         * hidden.py), in the JSON Lines and summary walks; anything else is the Python path's */
        if (!takes_notes(w, MS_TPL_BAD_CRC) || is_signed ||
            f[size - 1] == MS_STX_V2 || f[size - 1] == MS_STX_V1 || (k > 0 && w->fbad[k - 1]))
            return NOT_CLEAN;
        bad = 1;
    }
    int known = ms_signer_has(w, sender);
    for (size_t i = 0; i < *t && !known; i++)
        known = w->tentative[i] == sender;
    if (is_signed) {
        if (w->sign_mode == MS_SIGNED_VERIFY) {
            const int v = verify_signed(w, f, size, k);
            if (v != CLEAN)
                return v;
        } else if (w->sign_mode != MS_SIGNED_NOKEY) {
            return NOT_CLEAN;
        }
        if (!known) {
            if (grow((void **)&w->tentative, &w->cap_tentative, *t + 1, sizeof *w->tentative) != 0)
                return NOMEM;
            w->tentative[(*t)++] = (uint16_t)sender;
        }
    }
    uint8_t fnote = MS_FNOTE_NONE;
    if (!is_signed && known) {
        /* an unsigned frame of a sender that signs: its note, which the JSON Lines and summary walks write
         * (security/stage.py unsigned_note), the column mode with `notes` as a code; the statistics mode
         * hands it back */
        if (!takes_notes(w, 0))
            return NOT_CLEAN;
        if (m->msgid != RADIO_STATUS)
            fnote = f[0] == MS_STX_V2 ? MS_FNOTE_UNSIGNED : MS_FNOTE_V1;
    }
    if (grow((void **)&w->frames, &w->cap_frames, 2 * k + 2, sizeof *w->frames) != 0 ||
        grow((void **)&w->fnote, &w->cap_fnote, k + 1, sizeof *w->fnote) != 0 ||
        grow((void **)&w->fbad, &w->cap_fbad, k + 1, sizeof *w->fbad) != 0)
        return NOMEM;
    w->fnote[k] = fnote;
    w->fbad[k] = bad;
    w->frames[2 * k] = (uint32_t)pos;
    w->frames[2 * k + 1] = (uint32_t)size;
    return CLEAN;
}

/* Whether d[0..n) is a run of frames the native path writes; their (position, size) in w->frames. */
static int scan_clean(ms_walker *w, const uint8_t *d, size_t n, size_t *count, size_t *nsigners) {
    size_t k = 0, t = 0, pos = 0;
    w->n_pending = 0;
    while (pos < n) {
        const int r = clean_frame(w, d, pos, n, k, &t);
        if (r != CLEAN)
            return r;
        pos += w->frames[2 * k + 1];
        k++;
    }
    *count = k;
    *nsigners = t;
    return CLEAN;
}

#define LINE_FIXED_MAX 512 /* the keys, header numbers and the signature object of one line */
#define LINE_SLACK 128     /* fixed-size copies write up to this much past the text they copy */
#define MID_MAX (64 + 2 * MS_ENDPOINT_MAX + MS_DOUBLE_MAX)
#define LEAD_MAX 48
#define LINE_ROOM (LEAD_MAX + MID_MAX + LINE_FIXED_MAX + LINE_SLACK) /* + name and fields of the message */

/* One JSON line per frame of a clean datagram. `lead` is `{"frame":N,"index":`, `mid` everything from
 * `,"time":` to `"version":`; `has_time`, `t`: the record's time (a judged signature's skew). Room is
 * made once per line for the most it can hold. */
static int write_frames(ms_walker *w, ms_buf *out, const uint8_t *d, size_t count, const char *lead,
                        size_t lead_len, const char *mid, size_t mid_len, int has_time, double t, uint64_t base,
                        uint64_t raw_first) {
    for (size_t i = 0; i < count; i++) {
        const uint8_t *f = d + w->frames[2 * i];
        const size_t size = w->frames[2 * i + 1];
        const int v2 = f[0] == MS_STX_V2;
        const size_t hlen = v2 ? MS_HEADER_V2 : MS_HEADER_V1;
        const size_t len = f[1];
        const uint32_t msgid = v2 ? (uint32_t)f[7] | ((uint32_t)f[8] << 8) | ((uint32_t)f[9] << 16) : f[5];
        const ms_message *m = ms_table_get(w->table, msgid); /* found by scan_clean */
        const int fnote = w->fnote[i];
        const size_t room = LINE_ROOM + m->name_len + m->json_max + MS_SIGNATURE_VALID_EXTRA +
                            (fnote ? 4 * MS_NOTE_TPL_MAX + m->name_len + 40 : 0) +
                            (w->fbad[i] ? 3 * MS_NOTE_TPL_MAX + 40 : 0);
        (void)lead_len;
        char *const start = ms_buf_room(out, room);
        if (start == NULL)
            return -1;
        char *p = start;
        if (raw_first) { /* a raw stream's frame is a record of its own (numbered across the stream), index 1 */
            p = MS_W_LIT(p, "{\"frame\":");
            p = ms_w_u64(p, raw_first + i);
            p = MS_W_LIT(p, ",\"index\":1");
        } else {
            memcpy(p, lead, LEAD_MAX); /* fixed-size copies: the room has the slack */
            p += lead_len;
            p = ms_w_u64(p, i + 1);
        }
        if (mid_len <= LINE_SLACK)
            memcpy(p, mid, LINE_SLACK);
        else
            memcpy(p, mid, mid_len);
        p += mid_len;
        *p++ = v2 ? '2' : '1';
        p = MS_W_LIT(p, ",\"len\":");
        p = ms_w_u8(p, (unsigned)len);
        p = MS_W_LIT(p, ",\"incompat_flags\":");
        p = ms_w_u8(p, v2 ? f[2] : 0);
        p = MS_W_LIT(p, ",\"compat_flags\":");
        p = ms_w_u8(p, v2 ? f[3] : 0);
        p = MS_W_LIT(p, ",\"seq\":");
        p = ms_w_u8(p, f[v2 ? 4 : 2]);
        p = MS_W_LIT(p, ",\"sysid\":");
        p = ms_w_u8(p, f[v2 ? 5 : 3]);
        p = MS_W_LIT(p, ",\"compid\":");
        p = ms_w_u8(p, f[v2 ? 6 : 4]);
        p = MS_W_LIT(p, ",\"msgid\":");
        p = ms_w_u32(p, msgid);
        p = MS_W_LIT(p, ",\"msgname\":");
        p = ms_w_padded(p, m->name, m->name_len);
        p = MS_W_LIT(p, ",\"crc\":");
        p = ms_w_u32(p, ms_le16(f + hlen + len));
        const int bad = w->fbad[i];
        if (bad)
            p = MS_W_LIT(p, ",\"crc_status\":\"bad\",\"fields\":");
        else
            p = MS_W_LIT(p, ",\"crc_status\":\"ok\",\"fields\":");
        p = ms_w_fields(p, m, f + hlen, len);
        if (v2 && (f[2] & 1)) {
            p = MS_W_LIT(p, ",\"signature\":");
            if (w->sign_mode == MS_SIGNED_VERIFY) {
                const ms_sign_key *key = &w->signing->keys[w->sig_keys[i]]; /* set by verify_signed */
                p = ms_w_signature_valid(p, f + size - MS_SIGNATURE_LEN, key->name, key->name_len, has_time, t);
            } else {
                p = ms_w_signature_nokey(p, f + size - MS_SIGNATURE_LEN);
            }
            p = MS_W_LIT(p, ",\"encryption\":null,\"notes\":[]}\n");
        } else if (fnote || bad) {
            p = MS_W_LIT(p, ",\"signature\":null,\"encryption\":null,\"notes\":[");
            if (bad) { /* the framer's note first (build_frame), then the security stage's */
                char *const *b = w->note_tpl[MS_TPL_BAD_CRC];
                const size_t *bl = w->note_tpl_len[MS_TPL_BAD_CRC];
                static const char hex[] = "0123456789abcdef";
                const unsigned crc = ms_le16(f + hlen + len);
                memcpy(p, b[0], bl[0]);
                p += bl[0];
                for (int sh = 12; sh >= 0; sh -= 4)
                    *p++ = hex[(crc >> sh) & 15];
                memcpy(p, b[1], bl[1]);
                p += bl[1];
                p = ms_w_u64(p, base + w->frames[2 * i]);
                memcpy(p, b[2], bl[2]);
                p += bl[2];
                if (!fnote) {
                    p = MS_W_LIT(p, "]}\n");
                    goto written;
                }
                *p++ = ',';
            }
            char *const *tpl = w->note_tpl[fnote - 1];
            const size_t *tl = w->note_tpl_len[fnote - 1];
            memcpy(p, tpl[0], tl[0]);
            p += tl[0];
            memcpy(p, m->name + 1, m->name_len - 2); /* the name's JSON text inside its quotes */
            p += m->name_len - 2;
            memcpy(p, tpl[1], tl[1]);
            p += tl[1];
            p = ms_w_u8(p, f[v2 ? 5 : 3]);
            *p++ = '/';
            p = ms_w_u8(p, f[v2 ? 6 : 4]);
            memcpy(p, tpl[2], tl[2]);
            p += tl[2];
            p = ms_w_u64(p, base + w->frames[2 * i]);
            memcpy(p, tpl[3], tl[3]);
            p += tl[3];
            p = MS_W_LIT(p, "]}\n");
        } else {
            p = MS_W_LIT(p, ",\"signature\":null,\"encryption\":null,\"notes\":[]}\n");
        }
    written:
        if ((size_t)(p - start) > room)
            abort(); /* the bound above is wrong: memory is already corrupt, stop here */
        out->len += (size_t)(p - start);
    }
    return 0;
}

/* The source of a datagram written natively: a source of valid MAVLink (the Dissector's
 * mavlink_endpoints). */
static int note_source(ms_walker *w, const ms_udp *udp) {
    ms_endpoint e;
    memset(&e, 0, sizeof e);
    e.v6 = (uint8_t)udp->v6;
    memcpy(e.addr, udp->src, udp->v6 ? 16 : 4);
    e.port = udp->sport;
    return note_endpoint(w, &e);
}

/* Whether the datagram's source (`dst` 0) or destination (1) is an endpoint this walker knows. */
static int end_seen(const ms_walker *w, const ms_udp *udp, int dst) {
    ms_endpoint e;
    memset(&e, 0, sizeof e);
    e.v6 = (uint8_t)udp->v6;
    memcpy(e.addr, dst ? udp->dst : udp->src, udp->v6 ? 16 : 4);
    e.port = dst ? udp->dport : udp->sport;
    return seen_has(w, &e);
}

/* A datagram from a source Python's mavlink_endpoints would not take: the set is full (Dissector._learn) and
 * the source is not in it. Python dissects it, and says the give-up on the same record as the pure path. */
static int source_refused(const ms_walker *w, const ms_udp *udp) {
    if (w->n_new_endpoints < w->endpoint_room)
        return 0;
    return !end_seen(w, udp, 0);
}

/* The frames of a record written natively: counted, and what Python's Dissector._index would hold. */
static int count_frames(ms_walker *w, const uint8_t *d, size_t count) {
    w->frames_native += count;
    for (size_t i = 0; i < count; i++) {
        if (d[w->frames[2 * i]] == MS_STX_V1 || w->fbad[i]) { /* Python's fast path stops there: its scanner
                                                                 counts them all */
            w->py_index = (int64_t)count;
            break;
        }
    }
    return MS_WALK_FULL;
}

/* The summary lines of a clean record (summary.h), before anything is committed to the shared state:
 * MS_WALK_FULL when written, MS_WALK_HANDBACK (nothing written) when a value needs the Python path. */
static int write_summary_record(ms_walker *w, const ms_record *rec, ms_buf *out, const uint8_t *d, size_t count,
                                int has_time, double t, const ms_udp *udp) {
    char src[MS_ENDPOINT_TEXT], prefix[MS_PREFIX_MAX];
    int src_len = 0, dst_len = 0;
    const char *dst = NULL;
    if (udp != NULL) {
        memcpy(src, endpoint_text(w, udp->v6, udp->src, udp->sport, &src_len), MS_ENDPOINT_TEXT);
        dst = endpoint_text(w, udp->v6, udp->dst, udp->dport, &dst_len);
    }
    size_t n = ms_summary_prefix(prefix, has_time, t, w->has_t0, w->t0, udp != NULL ? src : NULL, (size_t)src_len,
                                 dst, (size_t)dst_len);
    if (n == 0)
        return MS_WALK_HANDBACK;
    const size_t mark = out->len;
    int r = ms_write_summary(w->summary, out, rec->number, prefix, n, d, w->frames, w->fbad, count);
    if (r < 0)
        return MS_WALK_NOMEM;
    if (r > 0) {
        out->len = mark;
        return MS_WALK_HANDBACK;
    }
    return MS_WALK_FULL;
}

/* Whether the datagram goes to a UDP port whose receivers are in a frame (w->waiting: the ports of
 * mavscope.mavlink.receivers.Sockets, only while a datagram to them ended in a frame). The port alone: a socket
 * bound to the wildcard address reads the datagrams to its unicast, broadcast and IPv4-mapped addresses alike. */
static int is_waiting(const ms_walker *w, const ms_udp *udp) {
    for (size_t i = 0; i < w->n_waiting; i++)
        if (w->waiting[i].port == udp->dport)
            return 1;
    return 0;
}

/* A datagram Python's Dissector._trusted takes for MAVLink without a CRC-valid frame: to or from one of
 * MAVLink's ports, or a source of valid MAVLink this walker knows (others: Python decides). */
static int trusted(const ms_walker *w, const ms_udp *udp) {
    for (size_t i = 0; i < w->nports; i++)
        if (w->ports[i] == udp->sport || w->ports[i] == udp->dport)
            return 1;
    return end_seen(w, udp, 0) || end_seen(w, udp, 1);
}

/* What the security stage would have kept of the frames written: the `nsigners` senders seen signing (in
 * w->tentative) and the signing streams they advance (w->pending). 0, or -1 out of memory. */
static int commit_signing(ms_walker *w, size_t nsigners) {
    for (size_t i = 0; i < nsigners; i++) {
        unsigned s = w->tentative[i];
        if (ms_signer_has(w, s))
            continue;
        if (grow((void **)&w->new_signers, &w->cap_new_signers, w->n_new_signers + 1, sizeof *w->new_signers) != 0)
            return -1;
        ms_signer_set(w, s);
        w->new_signers[w->n_new_signers++] = (uint16_t)s;
    }
    for (size_t i = 0; i < w->n_pending; i++) /* the streams exist: no allocation, cannot fail */
        (void)ms_signing_put(w->signing, w->pending[i].stream, w->pending[i].last, w->pending[i].key);
    return 0;
}

/* MS_WALK_FULL when the record was written (or had nothing), MS_WALK_HANDBACK, or MS_WALK_NOMEM. */
static int walk_record(ms_walker *w, const ms_record *rec, ms_buf *out) {
    if (rec->notes->n != 0 || w->reader.kind == MS_KIND_RAW || w->hand_back_all)
        return MS_WALK_HANDBACK;
    double t = 0.0;
    int has_time = ms_record_time(rec, &t);
    if (has_time < 0)
        return MS_WALK_HANDBACK;
    const uint8_t *data = rec->data;
    const uint8_t *d;
    size_t n;
    ms_udp udp;
    int is_udp = 0;
    if (rec->linktype == MS_LINKTYPE_TLOG) {
        d = data;
        n = rec->len;
    } else {
        int r = ms_net_decode(rec->linktype, data, rec->len, &udp);
        if (r == MS_NET_SILENT)
            return MS_WALK_FULL;
        if (r == MS_NET_HANDBACK)
            return MS_WALK_HANDBACK;
        d = data + udp.start;
        n = udp.len;
        is_udp = 1;
        if (w->n_waiting != 0 && is_waiting(w, &udp))
            return MS_WALK_HANDBACK; /* its receivers read it on with a frame the last datagram began */
        if (source_refused(w, &udp))
            return MS_WALK_HANDBACK;
    }
    if (n > UINT32_MAX)
        return MS_WALK_HANDBACK;
    size_t count = 0, nsigners = 0;
    int clean = scan_clean(w, d, n, &count, &nsigners);
    if (clean == NOMEM)
        return MS_WALK_NOMEM;
    if (clean != CLEAN)
        return MS_WALK_HANDBACK;
    if (count == 0)
        return MS_WALK_FULL; /* an empty datagram */
    if (is_udp && w->fbad[0]) {
        int any_ok = 0;
        for (size_t i = 0; i < count && !any_ok; i++)
            any_ok = !w->fbad[i];
        if (!any_ok && !trusted(w, &udp))
            return MS_WALK_HANDBACK; /* no valid frame, no reason to expect MAVLink: Python decides */
    }
    if (w->summary != NULL) {
        int r = write_summary_record(w, rec, out, d, count, has_time, t, is_udp ? &udp : NULL);
        if (r != MS_WALK_FULL)
            return r;
    }
    /* commit what the Python path would have done to the shared state */
    if (commit_signing(w, nsigners) != 0)
        return MS_WALK_NOMEM;
    if (is_udp && !w->fbad[0] && note_source(w, &udp) != 0) /* (a source is learnt from a first frame that is valid) */
        return MS_WALK_NOMEM;
    if (w->summary != NULL)
        return count_frames(w, d, count);
    if (w->cols != NULL) {
        const uint8_t *notes = NULL;
        if (w->cols->notes) {
            for (size_t i = 0; i < count; i++) /* (nothing reads fnote after this in column mode) */
                w->fnote[i] = (uint8_t)(w->fnote[i] | (w->fbad[i] ? MS_NOTE_BAD_CRC : 0));
            notes = w->fnote;
        }
        if (ms_cols_record(w->cols, rec, d, w->frames, notes, count, has_time, t, is_udp ? &udp : NULL) != 0)
            return MS_WALK_NOMEM;
        return count_frames(w, d, count);
    }
    const char *src = NULL, *dst = NULL;
    int src_len = 0, dst_len = 0;
    if (is_udp) /* the cache may move the source's text: it is copied into `mid` before the destination's */
        src = endpoint_text(w, udp.v6, udp.src, udp.sport, &src_len);
    char lead[LEAD_MAX] = {0};
    memcpy(lead, "{\"frame\":", 9);
    size_t lead_len = (size_t)(ms_w_u64(lead + 9, rec->number) - lead);
    memcpy(lead + lead_len, ",\"index\":", 9);
    lead_len += 9;
    char mid[MID_MAX > LINE_SLACK ? MID_MAX : LINE_SLACK] = {0};
    size_t mid_len = 0;
#define MID(s)                                   \
    do {                                         \
        memcpy(mid + mid_len, s, sizeof(s) - 1); \
        mid_len += sizeof(s) - 1;                \
    } while (0)
    MID(",\"time\":");
    if (has_time)
        mid_len = (size_t)(ms_w_double(mid + mid_len, t) - mid);
    else
        MID("null");
    if (is_udp) {
        MID(",\"transport\":\"udp\",\"src\":\"");
        memcpy(mid + mid_len, src, (size_t)src_len);
        mid_len += (size_t)src_len;
        MID("\",\"dst\":\"");
        dst = endpoint_text(w, udp.v6, udp.dst, udp.dport, &dst_len);
        memcpy(mid + mid_len, dst, (size_t)dst_len);
        mid_len += (size_t)dst_len;
        MID("\",\"version\":");
    } else {
        MID(",\"transport\":\"tlog\",\"src\":null,\"dst\":null,\"version\":");
    }
#undef MID
    if (write_frames(w, out, d, count, lead, lead_len, mid, mid_len, has_time, t,
                     rec->offset + (uint64_t)(d - rec->data), 0) != 0)
        return MS_WALK_NOMEM;
    return count_frames(w, d, count);
}

/* ---- raw byte streams (docs/native.md, "What C writes and what it hands back") ----------------------------
 *
 * Python's StreamFramer (mavlink/framing.py) reads a raw file as the reader's 64 KiB chunks, each fed and taken
 * in turn. Fed more bytes while it is idle (RawLink.held -1: no byte, note or receiver out of step held), it
 * reads them as a fresh framer would: a frame here that is whole in the chunk, CRC-valid (or bad, unsigned, not
 * ending in an STX byte and followed by a CRC-valid frame whole in the chunk: the framer's test) and clean as
 * scan_clean judges a datagram's frames is exactly the frame, with no note, that the framer would give; so
 * such a stretch is written here, numbered on from RawLink.frames.
 *
 * Where no such frame starts, a piece is handed back, from there to a cut at `X`: the end of a frame `Q` the
 * framer shows CRC-valid (known message, no unknown incompat flag) at or after the piece's start, such that
 * every STX byte `q` from where Python's framer's bytes begin up to Q has what the framer and MAVLink's C
 * parser models (hidden.py) may read from it before Q: its frame (LEN) and, after it, one byte or the whole
 * frame that starts there (the framer's test of a damaged frame). Then neither reads past X in that piece
 * (Framer.scan never stops to wait for bytes, so it makes the decisions it makes over the whole chunk; it
 * lands on Q, as every frame it could take before Q ends by Q; the receivers' walks meet it at Q at the
 * latest), and the framer is idle after the piece. Where no such Q is in the chunk, the piece goes to the
 * chunk's end, as the pure path's chunk does; the next pieces are judged from where the bytes the framer
 * still holds begin (`carry` keeps those of the chunk before), until it is idle again. */

static inline int is_stx(uint8_t b) { return b == MS_STX_V2 || b == MS_STX_V1; }

/* The stream's bytes from carry_base to `end`: the carry, then the chunk from file offset `base`. */
typedef struct {
    const uint8_t *carry;
    uint64_t carry_base;
    const uint8_t *data;
    uint64_t base, end;
} raw_view;

static inline uint8_t view_at(const raw_view *v, uint64_t off) {
    return off >= v->base ? v->data[off - v->base] : v->carry[off - v->carry_base];
}

/* framing.py frame_size of the frame at `off` (its STX, LEN and INCOMPAT bytes are there) */
static size_t view_size(const raw_view *v, uint64_t off) {
    const size_t len = view_at(v, off + 1);
    if (view_at(v, off) == MS_STX_V2)
        return MS_HEADER_V2 + len + 2 + ((view_at(v, off + 2) & 1) ? MS_SIGNATURE_LEN : 0);
    return MS_HEADER_V1 + len + 2;
}

/* Whether a frame the framer calls CRC-valid starts at `off`, whole by v->end (framing.py _check_at VALID: a
 * message the table knows, its CRC). */
static int view_valid(const ms_walker *w, const raw_view *v, uint64_t off) {
    if (off + 3 > v->end || !is_stx(view_at(v, off)))
        return 0;
    const size_t size = view_size(v, off);
    if (off + size > v->end)
        return 0;
    uint8_t tmp[MS_HEADER_V2 + 255 + 2 + MS_SIGNATURE_LEN];
    const uint8_t *f;
    if (off >= v->base) {
        f = v->data + (off - v->base);
    } else {
        for (size_t i = 0; i < size; i++)
            tmp[i] = view_at(v, off + i);
        f = tmp;
    }
    const int v2 = f[0] == MS_STX_V2;
    const size_t hlen = v2 ? MS_HEADER_V2 : MS_HEADER_V1, len = f[1];
    const uint32_t msgid = v2 ? (uint32_t)f[7] | ((uint32_t)f[8] << 8) | ((uint32_t)f[9] << 16) : f[5];
    const ms_message *m = ms_table_get(w->table, msgid);
    if (m == NULL)
        return 0;
    uint16_t crc = ms_crc16(f + 1, hlen - 1 + len, 0xFFFF);
    crc = ms_crc16(&m->crc_extra, 1, crc);
    return crc == ms_le16(f + hlen + len) || w->fuzz_any_crc;
}

/* Framer.scan's next STX from `off` (the end when there is none) */
static uint64_t view_next_stx(const raw_view *v, uint64_t off) {
    while (off < v->end && !is_stx(view_at(v, off)))
        off++;
    return off;
}

/* Where a piece handed back from `from` ends (a file offset), Python's framer going on at `resume` (<= from):
 * Framer.scan over the view with `final` False, step for step, keeping `reach` (one past the furthest byte
 * its decisions read), until it takes a CRC-valid frame Q (no unknown incompat flag) that ends after `from`
 * and by which everything read before it ends: the end of Q. Where it stops to wait for bytes first, or
 * finds no such Q, the chunk's end. */
static uint64_t raw_cut(const ms_walker *w, const raw_view *v, uint64_t resume, uint64_t from) {
    const uint64_t end = v->end;
    uint64_t pos = resume, reach = resume, run_to = 0;
#define READ(x) do { if ((x) > reach) reach = (x); } while (0)
    while (pos < end) {
        const uint8_t b = view_at(v, pos);
        if (!is_stx(b)) {
            pos = view_next_stx(v, pos + 1);
            READ(pos + 1);
            continue;
        }
        if (pos + 3 > end)
            return end; /* (too short to tell: the scan waits) */
        const size_t size = view_size(v, pos);
        if (pos + size > end)
            return end; /* truncated: the scan waits */
        const int ok = view_valid(w, v, pos);
        if (ok) {
            if (reach <= pos + size && pos + size > from && !(b == MS_STX_V2 && (view_at(v, pos + 2) & ~1u)))
                return pos + size;
            READ(pos + size);
            pos += size;
            continue;
        }
        READ(pos + size);
        const uint64_t after = pos + size;
        if (after >= end)
            return end; /* a damaged frame to the end: the scan waits for the proof */
        int valid = 0; /* _check_at(after) */
        READ(after + 1);
        if (is_stx(view_at(v, after))) {
            if (after + 3 > end)
                return end;
            const size_t next = view_size(v, after);
            if (after + next > end)
                return end;
            READ(after + next);
            valid = view_valid(w, v, after);
        }
        if (valid) { /* a damaged frame the valid one after it ends */
            pos = after;
            continue;
        }
        if (pos + 1 < end && view_at(v, pos + 1) == b) { /* in a run of one STX byte */
            if (pos >= run_to) {
                run_to = pos;
                while (run_to < end && view_at(v, run_to) == b)
                    run_to++;
                READ(run_to + 1);
            }
            const uint64_t jump = run_to + 1 >= 2 * (uint64_t)size ? run_to + 1 - 2 * (uint64_t)size : 0;
            pos = jump > pos + 1 ? jump : pos + 1;
        } else {
            READ(pos + 2);
            pos = view_next_stx(v, pos + 1);
            READ(pos + 1);
        }
    }
#undef READ
    return end;
}

/* Keep the bytes Python's framer holds at the end of the chunk just walked (w->raw_held of them) before the
 * next chunk is read over it. 0, or -1 out of memory. */
static int raw_keep(ms_walker *w) {
    const ms_record *c = &w->raw_rec;
    const size_t held = w->raw_held > 0 ? (size_t)w->raw_held : 0;
    if (c->data == NULL || held == 0) {
        w->carry_len = 0;
        w->carry_base = c->data == NULL ? 0 : c->offset + c->len;
        w->carry_ok = c->data != NULL;
        return 0;
    }
    const size_t old = w->carry_ok ? w->carry_len : 0;
    if (held > MS_RAW_CARRY || held > old + c->len) {
        w->carry_len = 0;
        w->carry_ok = 0; /* not kept: the pieces go to the chunks' ends until the framer is idle */
        return 0;
    }
    if (grow((void **)&w->carry, &w->cap_carry, held, 1) != 0)
        return -1;
    if (held > c->len) { /* some of them from the carry before */
        const size_t from_old = held - c->len;
        memmove(w->carry, w->carry + (old - from_old), from_old);
        memcpy(w->carry + from_old, c->data, c->len);
    } else {
        memcpy(w->carry, c->data + (c->len - held), held);
    }
    w->carry_len = held;
    w->carry_base = c->offset + c->len - held;
    w->carry_ok = 1;
    return 0;
}

#define RAW_PREFIX " " "          -" " " "raw                               " " " /* summary.c ms_summary_prefix's */

/* Write the stretch of clean frames from w->raw_pos of the chunk (Python's framer idle there), as far as it
 * goes (in column mode: into the columns, as far as their limit; *full then says the stretch stopped there, not
 * at damage): w->raw_pos moves past them. 0, or -1 out of memory. */
static int raw_run(ms_walker *w, ms_buf *out, int *full) {
    const ms_record *c = &w->raw_rec;
    const uint8_t *d = c->data;
    const size_t n = c->len, start = w->raw_pos;
    size_t pos = start, k = 0, t = 0, line = out->len;
    static const char prefix[] = RAW_PREFIX;
    const size_t room = w->cols != NULL ? (w->cols->n < w->cols->limit ? w->cols->limit - w->cols->n : 0) : SIZE_MAX;
    *full = 0;
    w->n_pending = 0;
    while (pos < n) {
        if (k >= room) {
            *full = 1; /* the next frames are the next chunk's (the framer is idle here all the same) */
            break;
        }
        const size_t t0 = t, p0 = w->n_pending;
        int r = clean_frame(w, d, pos, n, k, &t);
        if (r == NOMEM)
            return -1;
        const size_t here = out->len;
        if (r == CLEAN && w->summary != NULL) { /* its summary line now: an Info column Python writes stops here */
            const int s = ms_write_summary(w->summary, out, w->raw_frames + 1 + k, prefix, sizeof prefix - 1, d,
                                           w->frames + 2 * k, w->fbad + k, 1);
            if (s < 0)
                return -1;
            if (s > 0)
                r = NOT_CLEAN; /* (nothing written) */
        }
        if (r != CLEAN) {
            t = t0; /* (what the frame would have added to the signing state) */
            w->n_pending = p0;
            break;
        }
        line = here; /* where the last frame's line begins */
        pos += w->frames[2 * k + 1];
        k++;
    }
    if (k > 0 && w->fbad[k - 1]) { /* the framer takes a bad frame where a CRC-valid frame follows it (whole) */
        const raw_view v = {NULL, 0, d, c->offset, c->offset + n};
        if (!view_valid(w, &v, c->offset + pos)) {
            k--; /* (unsigned: it added nothing to the signing state) */
            pos -= w->frames[2 * k + 1];
            if (w->summary != NULL)
                out->len = line; /* its line goes */
        }
    }
    if (k == 0) {
        *full = 0; /* (a bad frame the limit stopped after, which no CRC-valid frame follows: a piece from it) */
        return 0;
    }
    const uint64_t first = w->raw_frames + 1;
    if (w->cols != NULL) { /* the rows the Python pipeline gives (Dissector._stream): columns.h ms_cols_raw */
        const uint8_t *notes = NULL;
        if (w->cols->notes) {
            for (size_t i = 0; i < k; i++) /* (nothing reads fnote after this in column mode) */
                w->fnote[i] = (uint8_t)(w->fnote[i] | (w->fbad[i] ? MS_NOTE_BAD_CRC : 0));
            notes = w->fnote;
        }
        if (ms_cols_raw(w->cols, d, c->offset, w->frames, notes, k, first) != 0)
            return -1;
    } else if (w->summary == NULL) {
        static const char mid_text[] = ",\"time\":null,\"transport\":\"raw\",\"src\":null,\"dst\":null,\"version\":";
        char mid[LINE_SLACK] = {0};
        memcpy(mid, mid_text, sizeof mid_text - 1);
        if (write_frames(w, out, d, k, NULL, 0, mid, sizeof mid_text - 1, 0, 0.0, c->offset, first) != 0)
            return -1;
    }
    if (commit_signing(w, t) != 0)
        return -1;
    w->frames_native += k;
    w->raw_frames += k;
    w->raw_pos = pos;
    if (start == 0 && pos == n)
        w->records_native++;
    w->walked = *c;
    w->walked.data = NULL;
    w->walked.notes = NULL;
    w->n_walked++;
    return 0;
}

/* One step of a raw stream's walk: MS_WALK_FULL (a stretch written, or a chunk begun), MS_WALK_HANDBACK (*rec a
 * piece for Python, or a record of the reader's notes), MS_WALK_END or MS_WALK_NOMEM. */
static int walk_raw(ms_walker *w, ms_buf *out, ms_record *rec) {
    if (!w->raw_have) {
        if (raw_keep(w) != 0)
            return MS_WALK_NOMEM;
        int got = ms_reader_next(&w->reader, &w->raw_rec);
        if (got < 0)
            return MS_WALK_NOMEM;
        if (got == 0)
            return MS_WALK_END;
        w->raw_pos = 0;
        if (w->raw_rec.notes->n != 0 || w->raw_rec.len == 0 || w->hand_back_all) {
            *rec = w->raw_rec; /* the reader's notes (a file that shrank, a failed read): the record as it is */
            w->raw_rec.data = NULL;
            w->carry_ok = 0;
            return MS_WALK_HANDBACK;
        }
        w->raw_have = 1;
        if (w->raw_held < 0)
            return MS_WALK_FULL;
    }
    const ms_record *c = &w->raw_rec;
    uint64_t resume;
    if (w->raw_held < 0) {
        int full = 0;
        if (raw_run(w, out, &full) != 0)
            return MS_WALK_NOMEM;
        if (w->raw_pos == c->len) {
            w->raw_have = 0;
            return MS_WALK_FULL;
        }
        if (full)
            return MS_WALK_FULL; /* the columns hold their limit: the stretch goes on in the next chunk */
        resume = c->offset + w->raw_pos;
    } else {
        const uint64_t at = c->offset + w->raw_pos;
        resume = (uint64_t)w->raw_held <= at ? at - (uint64_t)w->raw_held : 0;
    }
    const raw_view v = {w->carry, w->carry_base, c->data, c->offset, c->offset + c->len};
    uint64_t cut = v.end;
    if (resume >= c->offset ||
        (w->carry_ok && w->carry_base <= resume && w->carry_base + w->carry_len == c->offset))
        cut = raw_cut(w, &v, resume, c->offset + w->raw_pos);
    *rec = *c;
    rec->data = c->data + w->raw_pos;
    rec->len = (size_t)(cut - c->offset) - w->raw_pos;
    rec->offset = c->offset + w->raw_pos;
    rec->orig_len = rec->len;
    w->raw_pos = (size_t)(cut - c->offset);
    if (w->raw_pos == c->len)
        w->raw_have = 0;
    return MS_WALK_HANDBACK;
}

/* What ms_walk does with a step's result `r`: MS_WALK_NOMEM when the output failed, a hand-back counted and
 * returned, any other result but MS_WALK_FULL returned; MS_WALK_FULL (the step is done) goes on: -2. */
#define GO_ON (-2)
static int step_result(ms_walker *w, const ms_buf *out, int r) {
    if (out->failed)
        return MS_WALK_NOMEM;
    if (r == MS_WALK_HANDBACK)
        w->records_handed_back++;
    return r == MS_WALK_FULL ? GO_ON : r;
}

int ms_walk(ms_walker *w, ms_buf *out, size_t limit, ms_record *rec) {
    w->n_walked = 0;
    w->py_index = -1;
    while (out->len < limit && (w->cols == NULL || !ms_cols_full(w->cols))) {
        if (w->raw_native) {
            int r = step_result(w, out, walk_raw(w, out, rec));
            if (r != GO_ON)
                return r;
            continue;
        }
        int got = ms_reader_next(&w->reader, rec);
        if (got < 0)
            return MS_WALK_NOMEM;
        if (got == 0)
            return MS_WALK_END;
        int r = step_result(w, out, walk_record(w, rec, out));
        if (r != GO_ON)
            return r;
        w->walked = *rec;
        w->walked.data = NULL;
        w->walked.notes = NULL;
        w->n_walked++;
        w->records_native++;
    }
    return MS_WALK_FULL;
}
