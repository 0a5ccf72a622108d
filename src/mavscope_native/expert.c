/* The expert detectors of analysis/expert.py that look at every frame: SequenceAnomalies (its sequence
 * counters are StatsBuilder's, fed the same frames: the step comes from acc.c), CommandSources,
 * ReplayedCommands (on the channels' steps, its copies held per channel until the frames after them tell,
 * and the copies it has seen: past MS_K_COPIES_KEPT, `full`, the pure path forgets and says it) and UnsignedCommands; then ControlSources (control.c) and GnssAnomalies (gnss.c). */
#include <stdlib.h>
#include <string.h>

#include "acc.h"
#include "table.h"

/* ---- decoded fields --------------------------------------------------------------------------- */

static uint64_t le(const ms_acc_frame *f, size_t off, size_t n) {
    uint64_t v = 0;
    for (size_t i = 0; i < n; i++)
        if (off + i < f->payload_len) /* the payload is zero-padded to the message's length */
            v |= (uint64_t)f->payload[off + i] << (8 * i);
    return v;
}

ms_val ms_get(const ms_acc_frame *f, const ms_plan_msg *pm, int slot) {
    ms_val v = {0, 0, 0, 0.0};
    const ms_slot *s = &pm->slots[slot];
    if (s->type == 0 || f->payload == NULL)
        return v;
    v.has = 1;
    uint64_t u;
    switch (s->type) {
    case MS_T_U8: v.i = (int64_t)le(f, s->offset, 1); break;
    case MS_T_I8: v.i = (int8_t)le(f, s->offset, 1); break;
    case MS_T_U16: v.i = (int64_t)le(f, s->offset, 2); break;
    case MS_T_I16: v.i = (int16_t)le(f, s->offset, 2); break;
    case MS_T_U32: v.i = (int64_t)le(f, s->offset, 4); break;
    case MS_T_I32: v.i = (int32_t)le(f, s->offset, 4); break;
    case MS_T_U64: /* as float(v): correctly rounded (the plan allows it only where Python converts it) */
        u = le(f, s->offset, 8);
        v.i = u > INT64_MAX ? INT64_MAX : (int64_t)u;
        v.d = (double)u;
        return v;
    case MS_T_I64: v.i = (int64_t)le(f, s->offset, 8); break;
    case MS_T_F32: {
        uint32_t b = (uint32_t)le(f, s->offset, 4);
        float x;
        memcpy(&x, &b, 4);
        v.is_float = 1;
        v.d = (double)x;
        return v;
    }
    case MS_T_F64: {
        u = le(f, s->offset, 8);
        memcpy(&v.d, &u, 8);
        v.is_float = 1;
        return v;
    }
    default: v.has = 0; return v;
    }
    v.d = (double)v.i;
    return v;
}

/* expert._target: target_system, else MANUAL_CONTROL's target */
static ms_val target_of(const ms_acc_frame *f, const ms_plan_msg *pm) {
    return pm->slots[MS_F_TARGET_SYSTEM].type ? ms_get(f, pm, MS_F_TARGET_SYSTEM) : ms_get(f, pm, MS_F_TARGET);
}

static uint32_t label_of(const ms_acc_frame *f) {
    return f->known ? f->msgid : f->msgid | 0x80000000u; /* f.msgname or str(f.msgid) */
}

/* ---- the copies ReplayedCommands has seen: raw bytes -> record ------------------------------------ */

typedef struct {
    uint64_t hash, record;
    uint16_t len;
    uint8_t raw[MS_RAW_MAX];
} seen_entry;

struct ms_seen {
    seen_entry *e;
    uint32_t n, cap; /* entries, their capacity */
    int32_t *slots;
    uint32_t nslots;
};

void ms_seen_free(struct ms_seen *s) {
    if (s == NULL)
        return;
    free(s->e);
    free(s->slots);
    free(s);
}

static uint64_t raw_hash(const uint8_t *p, size_t n) {
    uint64_t h = 1469598103934665603ULL;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 1099511628211ULL;
    return h ^ (h >> 29);
}

static int32_t seen_find(const struct ms_seen *s, const uint8_t *raw, size_t n, uint64_t h) {
    uint32_t mask = s->nslots - 1;
    for (uint32_t i = (uint32_t)h & mask; s->slots[i] >= 0; i = (i + 1) & mask) {
        const seen_entry *e = &s->e[s->slots[i]];
        if (e->hash == h && e->len == n && memcmp(e->raw, raw, n) == 0)
            return s->slots[i];
    }
    return -1;
}

/* seen[raw] = record. A new entry past `kept`: 1 (the pure path forgets the newest but this one, and says
 * so: replays.ReplayedCommands.forgotten), so `full` is set. */
static int seen_put(ms_acc *a, const uint8_t *raw, size_t n, uint64_t h, int32_t k, uint64_t record) {
    struct ms_seen *s = a->seen;
    const uint32_t kept = (uint32_t)a->plan->k[MS_K_COPIES_KEPT];
    if (k >= 0) {
        s->e[k].record = record;
        return 0;
    }
    if (s->n >= kept)
        return 1;
    if (ms_vec_grow((void **)&s->e, &s->cap, s->n + 1, sizeof *s->e, kept) != 0)
        return -1;
    k = (int32_t)s->n++;
    seen_entry *e = &s->e[k];
    e->hash = h;
    e->record = record;
    e->len = (uint16_t)n;
    memcpy(e->raw, raw, n);
    uint32_t mask = s->nslots - 1;
    uint32_t i = (uint32_t)h & mask;
    while (s->slots[i] >= 0)
        i = (i + 1) & mask;
    s->slots[i] = k;
    return 0;
}

static int seen_init(ms_acc *a) {
    struct ms_seen *s = calloc(1, sizeof *s);
    if (s == NULL)
        return -1;
    uint32_t want = 4 * ((uint32_t)a->plan->k[MS_K_COPIES_KEPT] + 1), n = 16;
    while (n < want)
        n *= 2;
    s->slots = malloc((size_t)n * sizeof *s->slots);
    if (s->slots == NULL) {
        free(s);
        return -1;
    }
    memset(s->slots, 0xFF, (size_t)n * sizeof *s->slots);
    s->nslots = n;
    a->seen = s;
    return 0;
}

/* ---- findings in the making ------------------------------------------------------------------- */

/* ReplayedCommands._count: the link's entry in `which` (created in order), its frames and one `label`. */
int ms_count_named(ms_acc *a, int32_t *slot, ms_ivec *order, uint32_t key, const uint64_t *records, int nrec,
                       uint32_t label) {
    if (*slot < 0) {
        int g = ms_vec_grow((void **)&order->v, &order->cap, order->n + 1, sizeof *order->v, MS_CAP_ITEMS);
        if (g != 0)
            return g;
        int32_t at = ms_named_new(a, key);
        if (at < 0)
            return at == -1 ? -1 : 1;
        order->v[order->n++] = at;
        *slot = at;
    }
    ms_named *e = &a->named.v[*slot];
    for (int i = 0; i < nrec; i++)
        ms_fn_add(&e->fn, records[i], (uint32_t)a->plan->k[MS_K_MAX_FRAMES]);
    return ms_pairs_count(&a->names, (uint32_t)*slot, label, 1);
}

static int reported(ms_acc *a, uint64_t key) {
    uint32_t v;
    if (ms_map_get(&a->reported, key, &v))
        return 1;
    if (a->reported.n >= MS_CAP_ITEMS)
        return -2;
    return ms_map_put(&a->reported, key, 1) != 0 ? -1 : 0;
}

static int cmd_event(ms_acc *a, int kind, unsigned target, unsigned sender, uint32_t msgid, int32_t x, int32_t y,
                     uint64_t record) {
    int g = MS_VGROW(a, a->cmd_events, MS_CAP_ITEMS);
    if (g != 0)
        return g;
    ms_cmd_event *e = &a->cmd_events.v[a->cmd_events.n++];
    e->kind = (uint8_t)kind;
    e->target = (uint8_t)target;
    e->sender = (uint16_t)sender;
    e->msgid = msgid;
    e->a = x;
    e->b = y;
    e->record = record;
    return 0;
}

/* Commanded.add: `sender` commands vehicle `target`, counted the first time (0, -1 out of memory) */
static int commanded(ms_acc *a, unsigned target, unsigned sender, const ms_acc_frame *f) {
    ms_commanded *c = &a->commanded[target];
    if (c->senders == NULL && (c->senders = calloc(8192, 1)) == NULL)
        return -1;
    if (ms_bit(c->senders, sender))
        return 0;
    c->senders[sender >> 3] |= (uint8_t)(1u << (sender & 7));
    if (c->nshown < (uint32_t)a->plan->k[MS_K_COMMANDERS_SHOWN]) {
        c->shown_sender[c->nshown] = (uint16_t)sender;
        c->shown_msgid[c->nshown++] = f->msgid;
    }
    ms_fn_add(&c->fn, f->record, (uint32_t)a->plan->k[MS_K_MAX_FRAMES]);
    return 0;
}

/* CommandSources.add */
static int command_sources(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm, int fields) {
    const unsigned sender = (f->sysid << 8) | f->compid;
    if (f->msgid == 0) {
        a->heartbeat_seen[sender >> 3] |= (uint8_t)(1u << (sender & 7));
        if (fields) {
            ms_val t = ms_get(f, pm, MS_F_TYPE);
            if (t.has && !t.is_float && t.i == a->plan->k[MS_K_MAV_TYPE_GCS])
                a->cs_gcs[f->sysid >> 3] |= (uint8_t)(1u << (f->sysid & 7));
        }
        return 0;
    }
    if (!fields || !(pm->roles & MS_R_COMMANDING))
        return 0;
    ms_val tv = target_of(f, pm);
    if (!tv.has || tv.is_float || tv.i < 0 || tv.i > 255) /* not an int (the plan allows uint8 only) */
        return 0;
    const unsigned target = (unsigned)tv.i;
    if (ms_bit(a->cs_gcs, target) || target == f->sysid)
        return 0;
    if (a->first_commander[target] < 0)
        a->first_commander[target] = (int32_t)sender;
    const unsigned est = (unsigned)a->first_commander[target];
    int r;
    if ((est >> 8) != f->sysid && commanded(a, target, sender, f) != 0)
        return -1;
    if (f->src >= 0) {
        uint32_t known;
        if (!ms_map_get(&a->cs_endpoints, sender, &known)) {
            if (a->cs_endpoints.n >= MS_CAP_ITEMS)
                return 1;
            if (ms_map_put(&a->cs_endpoints, sender, (uint32_t)f->src) != 0)
                return -1;
            known = (uint32_t)f->src;
        }
        if (known != (uint32_t)f->src) {
            r = reported(a, 1ULL << 56 | (uint64_t)sender << 32 | (uint32_t)f->src);
            if (r < 0)
                return r == -1 ? -1 : 1;
            if (r == 0 && (r = cmd_event(a, 1, target, sender, f->msgid, f->src, (int32_t)known, f->record)) != 0)
                return r;
        }
    }
    if (!ms_bit(a->heartbeat_seen, sender)) {
        r = reported(a, 2ULL << 56 | sender);
        if (r < 0)
            return r == -1 ? -1 : 1;
        if (r == 0 && (r = cmd_event(a, 2, target, sender, f->msgid, 0, 0, f->record)) != 0)
            return r;
    }
    return 0;
}

/* ReplayedCommands: count the copy `c` of link `key` (its original and itself) */
static int count_copy(ms_acc *a, ms_link *lk, const ms_held_copy *c) {
    uint64_t records[2] = {c->orig, c->copy};
    return ms_count_named(a, &lk->copies, &a->copies, lk->sender, records, 2, c->label);
}

/* ReplayedCommands._count(..., (), name, n): `m`'s copies counted past the listed ones (no frame listed) */
static int count_more(ms_acc *a, ms_link *lk, const ms_held_more *m) {
    int r = ms_count_named(a, &lk->copies, &a->copies, lk->sender, NULL, 0, m->label);
    if (r == 0 && m->count > 1)
        r = ms_pairs_count(&a->names, (uint32_t)lk->copies, m->label, m->count - 1);
    return r;
}

/* The copies of a run, listed then counted per message, all counted as replays (then let go). */
static int count_run(ms_acc *a, ms_link *lk, ms_held_copies *listed, ms_held_mores *more) {
    int r;
    for (uint32_t i = 0; i < listed->n; i++)
        if ((r = count_copy(a, lk, &listed->v[i])) != 0)
            return r;
    for (uint32_t i = 0; i < more->n; i++)
        if ((r = count_more(a, lk, &more->v[i])) != 0)
            return r;
    listed->n = more->n = 0;
    return 0;
}

/* One more copy of a run: listed while it has fewer than MS_LISTED, else counted per message (`order`: the
 * order of the first of its message). 0, -1 nomem, 1 full (more than MS_MORE_MAX messages). */
static int hold_copy(ms_held_copies *listed, ms_held_mores *more, const ms_held_copy *c) {
    int g;
    if (listed->n < MS_LISTED) {
        if ((g = ms_vec_grow((void **)&listed->v, &listed->cap, listed->n + 1, sizeof *listed->v, MS_LISTED)) != 0)
            return g;
        listed->v[listed->n++] = *c;
        return 0;
    }
    for (uint32_t i = 0; i < more->n; i++)
        if (more->v[i].label == c->label) {
            more->v[i].count++;
            return 0;
        }
    if ((g = ms_vec_grow((void **)&more->v, &more->cap, more->n + 1, sizeof *more->v, MS_MORE_MAX)) != 0)
        return g;
    ms_held_more m = {1, c->order, c->label};
    more->v[more->n++] = m;
    return 0;
}

void ms_held_free(ms_held *h) {
    free(h->ahead.v);
    free(h->behind.v);
    free(h->ahead_more.v);
    free(h->behind_more.v);
}

/* ReplayedCommands._resolve_behind */
static int resolve_behind(ms_acc *a, ms_link *lk, ms_held *h, int step) {
    if (h->behind.n) {
        if (step == MS_STEP_NEXT || step == MS_STEP_GAP)
            return count_run(a, lk, &h->behind, &h->behind_more);
        if (step == MS_STEP_RESET)
            h->behind.n = h->behind_more.n = 0;
    }
    return 0;
}

/* ReplayedCommands._resolve: what the frame after them (number `seq`, `step`) tells of the copies held */
static int resolve(ms_acc *a, ms_link *lk, ms_held *h, unsigned seq, int step) {
    int r;
    if (h->ahead.n) {
        if (step == MS_STEP_NEXT || step == MS_STEP_GAP || step == MS_STEP_RESET) {
            h->ahead.n = h->ahead_more.n = 0;
        } else if (seq == h->ahead_seq && (step == MS_STEP_DUPLICATE || step == MS_STEP_UNCHANGED)) {
            if ((r = count_run(a, lk, &h->ahead, &h->ahead_more)) != 0)
                return r;
        }
    }
    return resolve_behind(a, lk, h, step);
}

/* ReplayedCommands.judge */
static int replayed_commands(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm, ms_link *lk, ms_chan *ch,
                             int step) {
    int r;
    const int replay = f->sig == MS_SIG_REPLAY;
    const int tracked = !replay && pm != NULL && (pm->roles & MS_R_COMMANDING) && f->crc == MS_CRC_OK;
    size_t n = 0;
    uint64_t hash = 0;
    int32_t k = -1;
    if (tracked) {
        if (a->seen == NULL && seen_init(a) != 0)
            return -1;
        n = f->raw_len < MS_RAW_MAX ? f->raw_len : MS_RAW_MAX;
        hash = raw_hash(f->raw, n);
        k = seen_find(a->seen, f->raw, n, hash);
    }
    ms_held *h = ch->held >= 0 ? &a->helds.v[ch->held] : NULL;
    if (h != NULL) {
        if (h->ahead.n && k >= 0 && step == MS_STEP_NEXT && !f->has_signature) { /* the run ahead goes on */
            ms_held_copy c = {0, a->seen->e[k].record, f->record, label_of(f)};
            if ((r = hold_copy(&h->ahead, &h->ahead_more, &c)) != 0)
                return r;
            return resolve_behind(a, lk, h, step);
        }
        if ((r = resolve(a, lk, h, f->seq, step)) != 0)
            return r;
    }
    if (replay)
        return ms_count_named(a, &lk->replays, &a->replays, lk->sender, &f->record, 1, label_of(f));
    if (!tracked)
        return 0;
    if (k >= 0 && f->has_signature) { /* the signature timestamp did not advance */
        ms_held_copy c = {0, a->seen->e[k].record, f->record, label_of(f)};
        return count_copy(a, lk, &c);
    }
    if (k < 0 || step == MS_STEP_FIRST || step == MS_STEP_NEXT || step == MS_STEP_LATE || step == MS_STEP_RESET)
        return seen_put(a, f->raw, n, hash, k, f->record);
    if (h == NULL) {
        int g = MS_VGROW(a, a->helds, MS_CAP_CHANNELS);
        if (g != 0)
            return g;
        ch->held = (int32_t)a->helds.n;
        h = &a->helds.v[a->helds.n++];
        memset(h, 0, sizeof *h);
        h->sender = lk->sender;
    }
    ms_held_copy c = {a->held_order, a->seen->e[k].record, f->record, label_of(f)};
    if (step == MS_STEP_GAP) {
        h->ahead.n = h->ahead_more.n = 0;
        h->ahead_seq = (uint8_t)f->seq;
        return hold_copy(&h->ahead, &h->ahead_more, &c);
    }
    a->held_order++;
    return hold_copy(&h->behind, &h->behind_more, &c);
}

typedef struct {
    uint64_t order;
    ms_held_copy c; /* a listed copy, or (`more`) the message and count of those counted */
    uint64_t more;  /* 0: a listed copy; else how many counted */
    uint16_t sender;
} left_copy;

static int by_order(const void *x, const void *y) {
    const uint64_t a = ((const left_copy *)x)->order, b = ((const left_copy *)y)->order;
    return a < b ? -1 : a > b;
}

/* ReplayedCommands.finish: the copies still behind their counter are replays, in the order they came (those
 * counted per message at the first's) */
int ms_expert_finish(ms_acc *a) {
    size_t n = 0;
    for (uint32_t i = 0; i < a->helds.n; i++)
        n += a->helds.v[i].behind.n + a->helds.v[i].behind_more.n;
    left_copy *left = n ? malloc(n * sizeof *left) : NULL;
    if (n && left == NULL)
        return -1;
    n = 0;
    for (uint32_t i = 0; i < a->helds.n; i++) {
        ms_held *h = &a->helds.v[i];
        for (uint32_t j = 0; j < h->behind.n; j++) {
            left_copy l = {h->behind.v[j].order, h->behind.v[j], 0, h->sender};
            left[n++] = l;
        }
        for (uint32_t j = 0; j < h->behind_more.n; j++) {
            const ms_held_more *m = &h->behind_more.v[j];
            left_copy l = {m->order, {m->order, 0, 0, m->label}, m->count, h->sender};
            left[n++] = l;
        }
        h->behind.n = h->behind_more.n = h->ahead.n = h->ahead_more.n = 0;
    }
    if (n) /* qsort(NULL, 0, ...) is undefined: no copy held */
        qsort(left, n, sizeof *left, by_order);
    int r = 0;
    for (size_t i = 0; i < n && r == 0; i++) {
        ms_link *lk = &a->links.v[a->link_of[left[i].sender]];
        if (left[i].more) {
            ms_held_more m = {left[i].more, left[i].order, left[i].c.label};
            r = count_more(a, lk, &m);
        } else {
            r = count_copy(a, lk, &left[i].c);
        }
    }
    free(left);
    return r;
}

/* UnsignedCommands.add */
static int unsigned_commands(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm, int fields) {
    if (f->has_signature) {
        a->signing[f->sysid >> 3] |= (uint8_t)(1u << (f->sysid & 7));
        return 0;
    }
    if (!fields || !(pm->roles & MS_R_COMMANDING))
        return 0;
    ms_val tv = target_of(f, pm);
    int64_t target = tv.has && !tv.is_float && tv.i >= 0 && tv.i <= 255 ? tv.i : -1;
    uint32_t key = ((f->sysid << 8) | f->compid) << 9 | (uint32_t)(target + 1);
    uint32_t at;
    int32_t slot = -1;
    if (ms_map_get(&a->candidate_index, key, &at))
        slot = (int32_t)at;
    int r = ms_count_named(a, &slot, &a->candidates, key, &f->record, 1, f->msgid);
    if (r == 0 && a->candidate_index.n < a->candidates.n)
        r = ms_map_put(&a->candidate_index, key, (uint32_t)slot);
    return r;
}

int ms_expert_add(ms_acc *a, const ms_acc_frame *f, ms_link *lk, ms_chan *ch, int step) {
    const ms_plan_msg *pm = f->known ? ms_plan_get(a->plan, f->msgid) : NULL;
    const int fields = pm != NULL && (pm->roles & MS_R_DECODE) && f->crc != MS_CRC_BAD && f->payload != NULL;
    int r;
    /* SequenceAnomalies (its counts are the links' `received`) */
    if (step == MS_STEP_DUPLICATE || step == MS_STEP_LATE || step == MS_STEP_UNCHANGED) {
        const int what = step == MS_STEP_DUPLICATE ? 0 : step == MS_STEP_LATE ? 1 : 2;
        if (lk->events[what] < 0) {
            int g = MS_VGROW(a, a->ev, MS_CAP_ITEMS);
            if (g != 0)
                return g;
            ms_event *e = &a->ev.v[a->ev.n];
            memset(e, 0, sizeof *e);
            e->sender = lk->sender;
            e->what = (uint8_t)what;
            lk->events[what] = (int32_t)a->ev.n++;
        }
        ms_fn_add(&a->ev.v[lk->events[what]].fn, f->record, (uint32_t)a->plan->k[MS_K_MAX_FRAMES]);
        if ((r = ms_pairs_count(&a->ev_labels, (uint32_t)lk->events[what], label_of(f), 1)) != 0)
            return r;
    }
    if (pm != NULL || f->msgid == 0)
        if ((r = command_sources(a, f, pm, fields)) != 0)
            return r;
    if ((r = replayed_commands(a, f, pm, lk, ch, step)) != 0)
        return r;
    if ((r = unsigned_commands(a, f, pm, fields)) != 0)
        return r;
    if (fields && (pm->roles & MS_R_CONTROL) && (r = ms_control_add(a, f, pm)) != 0)
        return r;
    if (fields && (pm->roles & MS_R_GNSS) && (r = ms_gnss_add(a, f, pm)) != 0)
        return r;
    return 0;
}
