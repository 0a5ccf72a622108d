/* SeqChannels and ChannelCounter (analysis/sequence.py): a sender's sequence tracker per channel, and each
 * channel's frames, whoever sent them, to tell the numbers a sender skipped that another id on the channel
 * used (one program sending as several ids on one counter). */
#include <string.h>

#include "acc.h"

/* SeqChannels.tracker: the sender's tracker for the frame's channel (NULL: a cap filled, `full` set, or
 * memory ran out). */
ms_chan *ms_channel(ms_acc *a, ms_link *lk, int32_t src, int32_t dst) {
    int32_t shared = -1;
    for (int32_t i = lk->chan_head; i >= 0; i = a->chans.v[i].next) {
        ms_chan *c = &a->chans.v[i];
        if (c->src == src && c->dst == dst)
            return c;
        if (c->src == MS_SHARED)
            shared = i;
    }
    if (lk->nchan && (lk->nchan >= (uint32_t)a->plan->k[MS_K_MAX_CHANNELS] ||
                      a->extra >= (uint64_t)a->plan->k[MS_K_MAX_EXTRA])) {
        if (shared >= 0)
            return &a->chans.v[shared];
        src = dst = MS_SHARED;
    }
    int g = MS_VGROW(a, a->chans, MS_CAP_CHANNELS);
    if (g != 0) {
        a->full = g > 0;
        return NULL;
    }
    int32_t counter = -1;
    if (src != MS_SHARED) {
        uint64_t key = (uint64_t)(uint32_t)src << 32 | (uint32_t)dst;
        uint32_t found;
        if (ms_map_get(&a->counter_index, key, &found)) {
            counter = (int32_t)found;
        } else {
            if ((g = MS_VGROW(a, a->counters, MS_CAP_CHANNELS)) != 0) {
                a->full = g > 0;
                return NULL;
            }
            if (ms_map_put(&a->counter_index, key, a->counters.n) != 0)
                return NULL;
            ms_counter *k = &a->counters.v[a->counters.n];
            memset(k, 0, sizeof *k);
            for (int i = 0; i < MS_RING; i++)
                k->ring[i] = -1;
            counter = (int32_t)a->counters.n++;
        }
    }
    a->extra += lk->nchan ? 1 : 0;
    int32_t at = (int32_t)a->chans.n++;
    ms_chan *c = &a->chans.v[at];
    c->src = src;
    c->dst = dst;
    c->next = -1;
    c->counter = counter;
    c->slot = -1;
    c->at = 0;
    c->sender = lk->sender;
    c->held = -1;
    ms_seq_init(&c->seq);
    if (lk->chan_tail >= 0)
        a->chans.v[lk->chan_tail].next = at;
    else
        lk->chan_head = at;
    lk->chan_tail = at;
    lk->nchan++;
    return c;
}

/* ChannelCounter.taken: of chan `ci`'s jump ahead to `seq`, the first numbers skipped another id heard on the
 * channel since its last frame used (*partner: that id's sender, -1). */
static unsigned taken(const ms_acc *a, int32_t ci, unsigned seq, int32_t *partner) {
    const ms_chan *c = &a->chans.v[ci];
    *partner = -1;
    if (c->counter < 0 || c->seq.last < 0)
        return 0;
    unsigned last = (unsigned)c->seq.last, d = (seq - last) & 0xFF, best = 0;
    if (d < 2 || d >= (unsigned)a->plan->k[MS_K_LATE_WINDOW])
        return 0;
    const ms_counter *k = &a->counters.v[c->counter];
    for (int i = 0; i < MS_RING; i++) {
        int32_t oi = k->ring[i];
        if (oi < 0 || oi == ci)
            continue;
        const ms_chan *o = &a->chans.v[oi];
        if (o->at <= c->at || o->seq.last < 0)
            continue;
        unsigned step = ((unsigned)o->seq.last - last) & 0xFF;
        if (best < step && step < d) {
            best = step;
            *partner = k->senders[i];
        }
    }
    return best;
}

/* the channel heard one more frame, chan `ci`'s (SeqChannels.feed, ChannelCounter.admit) */
static void heard(ms_acc *a, int32_t ci) {
    ms_chan *c = &a->chans.v[ci];
    if (c->counter < 0)
        return;
    ms_counter *k = &a->counters.v[c->counter];
    c->at = ++k->frames;
    if (c->slot < 0 || k->ring[c->slot] != ci) {
        c->slot = (int32_t)k->next;
        k->ring[k->next] = ci;
        k->senders[k->next] = c->sender;
        k->next = (k->next + 1) % MS_RING;
    }
}

/* SeqChannels.feed: frame `f` fed to its tracker `ch`: MS_STEP_*, or -1 when memory ran out. */
int ms_channel_feed(ms_acc *a, ms_chan *ch, const ms_acc_frame *f) {
    const int32_t ci = (int32_t)(ch - a->chans.v);
    int32_t partner;
    unsigned skipped = taken(a, ci, f->seq, &partner);
    int step = ms_seq_feed(&ch->seq, &a->rules, f->seq, f->record, f->raw, f->raw_len, skipped, partner);
    if (step >= 0)
        heard(a, ci);
    return step;
}
