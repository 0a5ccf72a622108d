#include "acc.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mavlink.h"

/* ---- small containers ------------------------------------------------------------------------- */

static uint64_t mix64(uint64_t x) {
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ULL;
    return x ^ (x >> 33);
}

int ms_map_get(const ms_map *m, uint64_t key, uint32_t *val) {
    if (m->cap == 0)
        return 0;
    uint32_t mask = m->cap - 1;
    for (uint32_t i = (uint32_t)mix64(key) & mask;; i = (i + 1) & mask) {
        if (m->vals[i] == UINT32_MAX)
            return 0;
        if (m->keys[i] == key) {
            *val = m->vals[i];
            return 1;
        }
    }
}

static void map_insert(uint64_t *keys, uint32_t *vals, uint32_t cap, uint64_t key, uint32_t val) {
    uint32_t mask = cap - 1;
    uint32_t i = (uint32_t)mix64(key) & mask;
    while (vals[i] != UINT32_MAX && keys[i] != key)
        i = (i + 1) & mask;
    keys[i] = key;
    vals[i] = val;
}

/* Insert or replace; -1 when memory runs out. */
int ms_map_put(ms_map *m, uint64_t key, uint32_t val) {
    if (m->cap == 0 || (m->n + 1) * 2 > m->cap) {
        uint32_t cap = m->cap ? m->cap * 2 : 64;
        uint64_t *keys = malloc((size_t)cap * sizeof *keys);
        uint32_t *vals = malloc((size_t)cap * sizeof *vals);
        if (keys == NULL || vals == NULL) {
            free(keys);
            free(vals);
            return -1;
        }
        memset(vals, 0xFF, (size_t)cap * sizeof *vals);
        for (uint32_t i = 0; i < m->cap; i++)
            if (m->vals[i] != UINT32_MAX)
                map_insert(keys, vals, cap, m->keys[i], m->vals[i]);
        free(m->keys);
        free(m->vals);
        m->keys = keys;
        m->vals = vals;
        m->cap = cap;
    }
    uint32_t mask = m->cap - 1;
    uint32_t i = (uint32_t)mix64(key) & mask;
    while (m->vals[i] != UINT32_MAX && m->keys[i] != key)
        i = (i + 1) & mask;
    if (m->vals[i] == UINT32_MAX)
        m->n++;
    m->keys[i] = key;
    m->vals[i] = val;
    return 0;
}

void ms_map_free(ms_map *m) {
    free(m->keys);
    free(m->vals);
    memset(m, 0, sizeof *m);
}

/* Room for `need` items; -1 out of memory, 1 when `need` is above `limit`. */
int ms_vec_grow(void **v, uint32_t *cap, uint32_t need, size_t item, uint32_t limit) {
    if (need > limit)
        return 1;
    if (need <= *cap)
        return 0;
    uint32_t c = *cap ? *cap : 16;
    while (c < need)
        c *= 2;
    void *p = realloc(*v, (size_t)c * item);
    if (p == NULL)
        return -1;
    *v = p;
    *cap = c;
    return 0;
}

void ms_fn_add(ms_fnums *fn, uint64_t number, uint32_t limit) {
    fn->count++;
    if (fn->n < limit && (fn->n == 0 || fn->nums[fn->n - 1] != number))
        fn->nums[fn->n++] = number;
}

int ms_pairs_count(ms_pairs *p, uint32_t owner, uint32_t value, uint64_t add) {
    uint64_t key = (uint64_t)owner << 32 | value;
    uint32_t at;
    if (ms_map_get(&p->index, key, &at)) {
        p->v[at].count += add;
        return 0;
    }
    int g = ms_vec_grow((void **)&p->v, &p->cap, p->n + 1, sizeof *p->v, p->limit);
    if (g != 0)
        return g;
    if (ms_map_put(&p->index, key, p->n) != 0)
        return -1;
    p->v[p->n].owner = owner;
    p->v[p->n].value = value;
    p->v[p->n].count = add;
    p->n++;
    return 0;
}

static void pairs_free(ms_pairs *p) {
    free(p->v);
    ms_map_free(&p->index);
    memset(p, 0, sizeof *p);
}

int32_t ms_named_new(ms_acc *a, uint32_t key) {
    int g = MS_VGROW(a, a->named, MS_CAP_ITEMS);
    if (g != 0)
        return g < 0 ? -1 : -2;
    ms_named *e = &a->named.v[a->named.n];
    memset(e, 0, sizeof *e);
    e->key = key;
    return (int32_t)a->named.n++;
}

/* ---- init, free, interning -------------------------------------------------------------------- */

int ms_acc_init(ms_acc *a, const ms_plan *plan) {
    memset(a, 0, sizeof *a);
    a->plan = plan;
    a->rules.gap_min = (int)plan->k[MS_K_GAP_MIN];
    a->rules.gaps_kept = (int)plan->k[MS_K_GAPS_KEPT];
    a->rules.reset_run = (int)plan->k[MS_K_RESET_RUN];
    a->last_stream = -1;
    a->rec_conv = -1;
    a->rec_src = a->rec_dst = -3;
    a->link_endpoints.limit = a->conv_systems.limit = MS_CAP_ENDS;
    /* the sequence findings' counted names: past expert.MAX_NAMED the pure path cuts their list */
    a->ev_labels.limit = plan->k[MS_K_MAX_NAMED] < MS_CAP_PAIRS ? (uint32_t)plan->k[MS_K_MAX_NAMED] : MS_CAP_PAIRS;
    a->names.limit = MS_CAP_PAIRS;
    a->link_of = malloc(65536 * sizeof *a->link_of);
    a->hb_of = malloc(65536 * sizeof *a->hb_of);
    if (a->link_of == NULL || a->hb_of == NULL) {
        ms_acc_free(a);
        return -1;
    }
    memset(a->link_of, 0xFF, 65536 * sizeof *a->link_of);
    memset(a->hb_of, 0xFF, 65536 * sizeof *a->hb_of);
    memset(a->first_commander, 0xFF, sizeof a->first_commander);
    memset(a->vehicle_addr, 0xFF, sizeof a->vehicle_addr);
    if (ms_acc_intern(a, "", 0) != 0) { /* id 0: "" (a conversation without a second endpoint) */
        ms_acc_free(a);
        return -1;
    }
    return 0;
}

void ms_acc_free(ms_acc *a) {
    for (uint32_t i = 0; i < a->streams.n; i++)
        free(a->streams.v[i].bins);
    free(a->streams.v);
    for (uint32_t i = 0; i < a->links.n; i++)
        ms_seq_free(&a->links.v[i].replay_seq);
    free(a->links.v);
    for (uint32_t i = 0; i < a->chans.n; i++)
        ms_seq_free(&a->chans.v[i].seq);
    free(a->chans.v);
    free(a->counters.v);
    ms_map_free(&a->counter_index);
    free(a->convs.v);
    free(a->link_of);
    free(a->hb_of);
    free(a->text);
    free(a->str_off);
    free(a->str_len);
    free(a->str_slots);
    ms_map_free(&a->stream_index);
    ms_map_free(&a->conv_index);
    pairs_free(&a->link_endpoints);
    pairs_free(&a->conv_systems);
    pairs_free(&a->names);
    pairs_free(&a->ev_labels);
    free(a->ev.v);
    free(a->named.v);
    free(a->copies.v);
    free(a->replays.v);
    ms_seen_free(a->seen);
    for (uint32_t i = 0; i < a->helds.n; i++)
        ms_held_free(&a->helds.v[i]);
    free(a->helds.v);
    free(a->candidates.v);
    ms_map_free(&a->candidate_index);
    ms_map_free(&a->reported);
    for (int i = 0; i < 256; i++)
        free(a->commanded[i].senders);
    ms_map_free(&a->cs_endpoints);
    free(a->cmd_events.v);
    free(a->hbs.v);
    free(a->intrusions.v);
    ms_map_free(&a->intrusion_index);
    free(a->ctl_events.v);
    free(a->gsenders.v);
    ms_map_free(&a->gsender_index);
    free(a->episodes.v);
    ms_map_free(&a->episode_index);
    memset(a, 0, sizeof *a);
}

static uint32_t str_hash(const char *s, size_t n) {
    uint32_t h = 2166136261u;
    for (size_t i = 0; i < n; i++)
        h = (h ^ (uint8_t)s[i]) * 16777619u;
    return h;
}

int32_t ms_acc_intern(ms_acc *a, const char *s, size_t n) {
    if (a->str_cap) {
        uint32_t mask = a->str_cap - 1;
        for (uint32_t i = str_hash(s, n) & mask; a->str_slots[i] >= 0; i = (i + 1) & mask) {
            int32_t id = a->str_slots[i];
            if (a->str_len[id] == n && memcmp(a->text + a->str_off[id], s, n) == 0)
                return id;
        }
    }
    if (a->nstr >= MS_CAP_STRINGS || n > 1024) {
        a->full = 1;
        return -2;
    }
    if ((a->nstr + 1) * 2 > a->str_cap) {
        uint32_t cap = a->str_cap ? a->str_cap * 2 : 256;
        int32_t *slots = malloc((size_t)cap * sizeof *slots);
        uint32_t *off = realloc(a->str_off, (size_t)cap * sizeof *off);
        if (off != NULL)
            a->str_off = off;
        uint32_t *len = realloc(a->str_len, (size_t)cap * sizeof *len);
        if (len != NULL)
            a->str_len = len;
        if (slots == NULL || off == NULL || len == NULL) {
            free(slots);
            return -1;
        }
        memset(slots, 0xFF, (size_t)cap * sizeof *slots);
        for (uint32_t id = 0; id < a->nstr; id++) {
            uint32_t i = str_hash(a->text + a->str_off[id], a->str_len[id]) & (cap - 1);
            while (slots[i] >= 0)
                i = (i + 1) & (cap - 1);
            slots[i] = (int32_t)id;
        }
        free(a->str_slots);
        a->str_slots = slots;
        a->str_cap = cap;
    }
    if (a->text_len + n + 1 > a->text_cap) {
        size_t cap = a->text_cap ? a->text_cap * 2 : 4096;
        while (cap < a->text_len + n + 1)
            cap *= 2;
        char *t = realloc(a->text, cap);
        if (t == NULL)
            return -1;
        a->text = t;
        a->text_cap = cap;
    }
    memcpy(a->text + a->text_len, s, n);
    a->text[a->text_len + n] = 0;
    int32_t id = (int32_t)a->nstr++;
    a->str_off[id] = (uint32_t)a->text_len;
    a->str_len[id] = (uint32_t)n;
    a->text_len += n + 1;
    uint32_t mask = a->str_cap - 1;
    uint32_t i = str_hash(s, n) & mask;
    while (a->str_slots[i] >= 0)
        i = (i + 1) & mask;
    a->str_slots[i] = id;
    return id;
}

/* ---- StatsBuilder ----------------------------------------------------------------------------- */

/* Python's (t - origin) / width bins, width doubling past RATE_BINS (RateHistogram.add). */
static int rates_add(ms_acc *a, ms_stream *s, double t) {
    const uint32_t nmax = (uint32_t)a->plan->k[MS_K_RATE_BINS];
    if (s->bins == NULL) {
        s->bins = calloc(nmax, sizeof *s->bins);
        if (s->bins == NULL)
            return -1;
        s->width = 1.0;
        s->has_rates = 1;
    }
    double i = t > a->first ? trunc((t - a->first) / s->width) : 0.0;
    while (i >= (double)nmax) {
        s->width *= 2;
        uint32_t n = (s->nbins + 1) / 2;
        for (uint32_t k = 0; k < n; k++)
            s->bins[k] = s->bins[2 * k] + (2 * k + 1 < s->nbins ? s->bins[2 * k + 1] : 0);
        for (uint32_t k = n; k < s->nbins; k++)
            s->bins[k] = 0;
        s->nbins = n;
        i = floor(i / 2);
    }
    uint32_t k = (uint32_t)i;
    if (k >= s->nbins)
        s->nbins = k + 1; /* the bins past the old end are zero */
    s->bins[k]++;
    return 0;
}

/* The frame's (sender, message) stream in *out: NULL past the first MS_K_MAX_STREAMS (StatsBuilder counts
 * the frame as unfollowed). 0, 1 when a cap filled (`full` set), -1 out of memory. */
static int stream(ms_acc *a, const ms_acc_frame *f, ms_stream **out) {
    uint64_t key = (uint64_t)f->sysid << 32 | (uint64_t)f->compid << 24 | f->msgid;
    *out = NULL;
    if (a->last_stream >= 0 && a->streams.v[a->last_stream].key == key) {
        *out = &a->streams.v[a->last_stream];
        return 0;
    }
    uint32_t at;
    if (!ms_map_get(&a->stream_index, key, &at)) {
        if (a->streams.n >= a->plan->k[MS_K_MAX_STREAMS])
            return 0;
        int g = MS_VGROW(a, a->streams, MS_CAP_STREAMS);
        if (g != 0)
            return g > 0 ? (a->full = 1) : -1;
        at = a->streams.n;
        if (ms_map_put(&a->stream_index, key, at) != 0)
            return -1;
        memset(&a->streams.v[at], 0, sizeof a->streams.v[at]);
        a->streams.v[at].key = key;
        a->streams.n++;
    }
    a->last_stream = (int32_t)at;
    *out = &a->streams.v[at];
    return 0;
}

static ms_link *link_for(ms_acc *a, unsigned sender) {
    int32_t at = a->link_of[sender];
    if (at >= 0)
        return &a->links.v[at];
    int g = MS_VGROW(a, a->links, MS_CAP_LINKS);
    if (g != 0) {
        a->full = g > 0;
        return NULL;
    }
    ms_link *lk = &a->links.v[a->links.n];
    memset(lk, 0, sizeof *lk);
    lk->sender = (uint16_t)sender;
    lk->chan_head = lk->chan_tail = -1;
    lk->events[0] = lk->events[1] = lk->events[2] = -1;
    lk->copies = lk->replays = -1;
    ms_seq_init(&lk->replay_seq);
    a->link_of[sender] = (int32_t)a->links.n++;
    return lk;
}

static int str_less_eq(const ms_acc *a, int32_t x, int32_t y) {
    size_t nx = a->str_len[x], ny = a->str_len[y];
    int c = memcmp(a->text + a->str_off[x], a->text + a->str_off[y], nx < ny ? nx : ny);
    return c < 0 || (c == 0 && nx <= ny);
}

/* The conversation of the frame in *out: a = str(src or transport), b = str(dst or ""), in order; NULL
 * past the first MS_K_MAX_CONVERSATIONS (unfollowed). 0, 1 when a cap filled (`full` set), -1 nomem. */
static int conversation(ms_acc *a, const ms_acc_frame *f, int *forward, ms_conv **out) {
    static const char *const NAMES[MS_TR_N] = {"udp", "tcp", "tlog", "raw"};
    int32_t x = f->src, y = f->dst < 0 ? 0 : f->dst;
    *out = NULL;
    if (x < 0) {
        x = ms_acc_intern(a, NAMES[f->transport], strlen(NAMES[f->transport]));
        if (x < 0)
            return x == -1 ? -1 : 1;
    }
    int32_t lo = x, hi = y;
    if (!str_less_eq(a, x, y)) {
        lo = y;
        hi = x;
    }
    *forward = lo == x; /* a == c.a */
    uint64_t key = (uint64_t)f->transport << 62 | (uint64_t)lo << 31 | (uint64_t)hi;
    uint32_t at;
    if (!ms_map_get(&a->conv_index, key, &at)) {
        if (a->convs.n >= a->plan->k[MS_K_MAX_CONVERSATIONS])
            return 0;
        int g = MS_VGROW(a, a->convs, MS_CAP_CONVS);
        if (g != 0)
            return g > 0 ? (a->full = 1) : -1;
        at = a->convs.n;
        if (ms_map_put(&a->conv_index, key, at) != 0)
            return -1;
        ms_conv *c = &a->convs.v[at];
        memset(c, 0, sizeof *c);
        c->a = lo;
        c->b = hi;
        c->transport = (uint8_t)f->transport;
        a->convs.n++;
    }
    *out = &a->convs.v[at];
    return 0;
}

#define SEE(o, f)                      \
    do {                               \
        if ((f)->has_time) {           \
            if (!(o)->has_time) {      \
                (o)->first = (f)->time; \
                (o)->has_time = 1;     \
            }                          \
            (o)->last = (f)->time;     \
        }                              \
    } while (0)

#define CHECK(x)                                   \
    do {                                           \
        if ((x) == NULL)                           \
            return a->full ? 1 : -1;               \
    } while (0)

int ms_acc_add(ms_acc *a, const ms_acc_frame *f) {
    if (a->full)
        return 1;
    const uint64_t size = f->raw_len;
    const unsigned sender = (f->sysid << 8) | f->compid;
    a->total++;
    a->nbytes += size;
    if (f->has_time) {
        if (!a->has_first) {
            a->first = f->time;
            a->has_first = 1;
        }
        a->last = f->time;
    }
    ms_stream *s;
    int r = stream(a, f, &s);
    if (r != 0)
        return r;
    if (s == NULL) {
        a->unfollowed_streams++;
    } else {
        s->count++;
        s->bytes += size;
        SEE(s, f);
        if (f->has_time && rates_add(a, s, f->time) != 0)
            return -1;
    }
    ms_link *lk = link_for(a, sender);
    CHECK(lk);
    lk->received++;
    lk->bytes += size;
    if (f->version == 1)
        lk->v1++;
    else
        lk->v2++;
    if (f->version == 1)
        a->v1++;
    else if (f->version == 2)
        a->v2++;
    lk->crc[f->crc]++;
    a->crc[f->crc]++;
    lk->sig[f->sig]++;
    a->sig[f->sig]++;
    ms_chan *ch = ms_channel(a, lk, f->src < 0 ? -1 : f->src, f->dst < 0 ? -1 : f->dst);
    CHECK(ch);
    int step = ms_channel_feed(a, ch, f);
    if (step < 0)
        return -1;
    SEE(lk, f);
    const uint32_t link_index = (uint32_t)(lk - a->links.v);
    if (f->src >= 0) {
        r = ms_pairs_count(&a->link_endpoints, link_index, (uint32_t)f->src, 0);
        if (r != 0)
            return r > 0 ? (a->full = 1) : -1;
    }
    int forward = 1;
    ms_conv *c = NULL;
    if (a->rec_conv >= 0 && a->rec_src == f->src && a->rec_dst == f->dst && a->convs.v[a->rec_conv].transport == f->transport) {
        c = &a->convs.v[a->rec_conv];
        forward = a->rec_forward;
    } else {
        if ((r = conversation(a, f, &forward, &c)) != 0)
            return r;
        if (c != NULL) {
            a->rec_conv = (int32_t)(c - a->convs.v);
            a->rec_src = f->src;
            a->rec_dst = f->dst;
            a->rec_forward = forward;
        }
    }
    if (c == NULL) {
        a->unfollowed_convs++;
    } else {
        if (forward) {
            c->frames_ab++;
            c->bytes_ab += size;
        } else {
            c->frames_ba++;
            c->bytes_ba += size;
        }
        SEE(c, f);
        r = ms_pairs_count(&a->conv_systems, (uint32_t)(c - a->convs.v), sender, 0);
        if (r != 0)
            return r > 0 ? (a->full = 1) : -1;
    }
    r = ms_expert_add(a, f, lk, ch, step);
    if (r > 0)
        a->full = 1;
    return r;
}

int ms_acc_record(ms_acc *a, uint64_t number, int has_time, double t, int udp, const char *src, size_t src_len,
                  const char *dst, size_t dst_len, const uint8_t *d, const uint32_t *frames, size_t count) {
    ms_acc_frame f;
    memset(&f, 0, sizeof f);
    f.record = number;
    f.has_time = has_time;
    f.time = t;
    f.transport = udp ? MS_TR_UDP : MS_TR_TLOG;
    f.src = f.dst = -1;
    if (udp) {
        f.src = ms_acc_intern(a, src, src_len);
        f.dst = ms_acc_intern(a, dst, dst_len);
        if (f.src < 0 || f.dst < 0)
            return f.src == -1 || f.dst == -1 ? -1 : 1;
    }
    f.known = 1;
    f.crc = MS_CRC_OK;
    for (size_t i = 0; i < count; i++) {
        const uint8_t *p = d + frames[2 * i];
        const size_t size = frames[2 * i + 1];
        const int v2 = p[0] == MS_STX_V2;
        const size_t hlen = v2 ? MS_HEADER_V2 : MS_HEADER_V1;
        f.raw = p;
        f.raw_len = size;
        f.version = v2 ? 2 : 1;
        f.seq = p[v2 ? 4 : 2];
        f.sysid = p[v2 ? 5 : 3];
        f.compid = p[v2 ? 6 : 4];
        f.msgid = v2 ? (uint32_t)p[7] | ((uint32_t)p[8] << 8) | ((uint32_t)p[9] << 16) : p[5];
        f.has_signature = v2 && (p[2] & 1);
        f.sig = f.has_signature ? MS_SIG_NOKEY : MS_SIG_UNSIGNED;
        f.payload = p + hlen;
        f.payload_len = p[1];
        int r = ms_acc_add(a, &f);
        if (r != 0)
            return r;
    }
    return 0;
}
