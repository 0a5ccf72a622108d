/* ms_acc_dump: the accumulator's whole state as one byte string for mavscope/native_stats.py, which reads it
 * with `struct` in this order (little-endian; "fn" is a FrameNumbers: u64 count, u32 n, u64 x n):
 *
 *   "MSSD" u32 4
 *   totals    u64 frames, bytes; u8 has_time; f64 first, last; u64 crc[4]; u64 signature[6]; u64 v1, v2;
 *             u64 unfollowed streams, unfollowed conversations (their frames)
 *   strings   u32 n; per string u32 length, bytes
 *   streams   u32 n; per stream u64 key; u64 count, bytes; u8 has_time; f64 first, last;
 *             u8 has_rates; f64 width; u32 nbins; u64 bins[nbins]
 *   links     u32 n; per link u16 sender; u64 received, bytes, v1, v2; u64 crc[4]; u64 signature[6];
 *             u8 has_time; f64 first, last; i32 events[3]; u32 nchan; per channel i32 src, dst;
 *             i64 lost, duplicates, repeats, unchanged, reordered, shared, full_steps, gap_steps,
 *             first_full; i32 partner; u64 large_gaps; u8 ngaps;
 *             per gap u64 record; u8 before, after, size, remaining, shared
 *   pairs     u32 n; per pair u32 owner, value; u64 count   (link endpoints: link, string)
 *   convs     u32 n; per conversation u8 transport; i32 a, b; u64 frames_ab, frames_ba, bytes_ab, bytes_ba;
 *             u8 has_time; f64 first, last
 *   pairs     (conversation systems: conversation, sender)
 *   events    u32 n; per event u16 sender; u8 what; fn
 *   pairs     (the messages of the events' frames: event, label)
 *   named     u32 n; per entry u32 key; i64 holder; u64 since; fn
 *   pairs     (counted names: entry, label)
 *   copies, replays, candidates, intrusions: each u32 n, i32 entries[n]
 *   signing   32 bytes (bitmap of sysids)
 *   commands  32 bytes (CommandSources.gcs); u32 n; per event u8 kind, target; u16 sender; u32 msgid;
 *             i32 a, b; u64 record; then u32 n; per vehicle with new commanders (by sysid) u8 target;
 *             u16 first commander; u8 nshown; per shown u16 sender, u32 msgid; fn (its count: how many)
 *   control   u32 n; per event u8 kind, vehicle, sender, holder, flag, why; u32 label;
 *             u64 record, since, req_record; f64 alt; u16 length, old mode; u16 length, new mode
 *   episodes  u32 n; per episode u8 code, kind; u16 sender; u8 flags; fn; f64 worst; f64 a[4]; i64 n[4]
 */
#include <string.h>

#include "acc.h"

static void u8(ms_buf *b, unsigned v) {
    ms_buf_byte(b, (char)(uint8_t)v);
}

static void un(ms_buf *b, uint64_t v, int n) {
    char *p = ms_buf_room(b, (size_t)n);
    if (p == NULL)
        return;
    for (int i = 0; i < n; i++)
        p[i] = (char)(uint8_t)(v >> (8 * i));
    b->len += (size_t)n;
}

static void f64(ms_buf *b, double d) {
    uint64_t v;
    memcpy(&v, &d, 8);
    un(b, v, 8);
}

static void fn(ms_buf *b, const ms_fnums *x) {
    un(b, x->count, 8);
    un(b, x->n, 4);
    for (uint32_t i = 0; i < x->n; i++)
        un(b, x->nums[i], 8);
}

static void pairs(ms_buf *b, const ms_pairs *p) {
    un(b, p->n, 4);
    for (uint32_t i = 0; i < p->n; i++) {
        un(b, p->v[i].owner, 4);
        un(b, p->v[i].value, 4);
        un(b, p->v[i].count, 8);
    }
}

static void ivec(ms_buf *b, const ms_ivec *v) {
    un(b, v->n, 4);
    for (uint32_t i = 0; i < v->n; i++)
        un(b, (uint32_t)v->v[i], 4);
}

static void seq(ms_buf *b, const ms_seq *s) {
    un(b, (uint64_t)s->lost, 8);
    un(b, (uint64_t)s->duplicates, 8);
    un(b, (uint64_t)s->repeats, 8);
    un(b, (uint64_t)s->unchanged, 8);
    un(b, (uint64_t)s->reordered, 8);
    un(b, (uint64_t)s->shared, 8);
    un(b, (uint64_t)s->full_steps, 8);
    un(b, (uint64_t)s->gap_steps, 8);
    un(b, (uint64_t)s->first_full, 8);
    un(b, (uint32_t)s->partner, 4);
    un(b, s->large_gaps, 8);
    u8(b, s->ngaps);
    for (unsigned i = 0; i < s->ngaps; i++) {
        un(b, s->gaps[i].record, 8);
        u8(b, s->gaps[i].before);
        u8(b, s->gaps[i].after);
        u8(b, s->gaps[i].size);
        u8(b, s->gaps[i].remaining);
        u8(b, s->gaps[i].shared);
    }
}

int ms_acc_dump(ms_acc *a, ms_buf *b) {
    if (ms_expert_finish(a) != 0) /* the copies ReplayedCommands still holds, judged first */
        return -1;
    ms_buf_put(b, "MSSD", 4);
    un(b, 4, 4);
    un(b, a->total, 8);
    un(b, a->nbytes, 8);
    u8(b, a->has_first);
    f64(b, a->first);
    f64(b, a->last);
    for (int i = 0; i < MS_CRC_N; i++)
        un(b, a->crc[i], 8);
    for (int i = 0; i < MS_SIG_N; i++)
        un(b, a->sig[i], 8);
    un(b, a->v1, 8);
    un(b, a->v2, 8);
    un(b, a->unfollowed_streams, 8);
    un(b, a->unfollowed_convs, 8);
    un(b, a->nstr, 4);
    for (uint32_t i = 0; i < a->nstr; i++) {
        un(b, a->str_len[i], 4);
        ms_buf_put(b, a->text + a->str_off[i], a->str_len[i]);
    }
    un(b, a->streams.n, 4);
    for (uint32_t i = 0; i < a->streams.n; i++) {
        const ms_stream *s = &a->streams.v[i];
        un(b, s->key, 8);
        un(b, s->count, 8);
        un(b, s->bytes, 8);
        u8(b, s->has_time);
        f64(b, s->first);
        f64(b, s->last);
        u8(b, s->has_rates);
        f64(b, s->width);
        un(b, s->nbins, 4);
        for (uint32_t k = 0; k < s->nbins; k++)
            un(b, s->bins[k], 8);
    }
    un(b, a->links.n, 4);
    for (uint32_t i = 0; i < a->links.n; i++) {
        const ms_link *lk = &a->links.v[i];
        un(b, lk->sender, 2);
        un(b, lk->received, 8);
        un(b, lk->bytes, 8);
        un(b, lk->v1, 8);
        un(b, lk->v2, 8);
        for (int k = 0; k < MS_CRC_N; k++)
            un(b, lk->crc[k], 8);
        for (int k = 0; k < MS_SIG_N; k++)
            un(b, lk->sig[k], 8);
        u8(b, lk->has_time);
        f64(b, lk->first);
        f64(b, lk->last);
        for (int k = 0; k < 3; k++)
            un(b, (uint32_t)lk->events[k], 4);
        un(b, lk->nchan, 4);
        for (int32_t c = lk->chan_head; c >= 0; c = a->chans.v[c].next) {
            un(b, (uint32_t)a->chans.v[c].src, 4);
            un(b, (uint32_t)a->chans.v[c].dst, 4);
            seq(b, &a->chans.v[c].seq);
        }
    }
    pairs(b, &a->link_endpoints);
    un(b, a->convs.n, 4);
    for (uint32_t i = 0; i < a->convs.n; i++) {
        const ms_conv *c = &a->convs.v[i];
        u8(b, c->transport);
        un(b, (uint32_t)c->a, 4);
        un(b, (uint32_t)c->b, 4);
        un(b, c->frames_ab, 8);
        un(b, c->frames_ba, 8);
        un(b, c->bytes_ab, 8);
        un(b, c->bytes_ba, 8);
        u8(b, c->has_time);
        f64(b, c->first);
        f64(b, c->last);
    }
    pairs(b, &a->conv_systems);
    un(b, a->ev.n, 4);
    for (uint32_t i = 0; i < a->ev.n; i++) {
        un(b, a->ev.v[i].sender, 2);
        u8(b, a->ev.v[i].what);
        fn(b, &a->ev.v[i].fn);
    }
    pairs(b, &a->ev_labels);
    un(b, a->named.n, 4);
    for (uint32_t i = 0; i < a->named.n; i++) {
        un(b, a->named.v[i].key, 4);
        un(b, (uint64_t)a->named.v[i].holder, 8);
        un(b, a->named.v[i].since, 8);
        fn(b, &a->named.v[i].fn);
    }
    pairs(b, &a->names);
    ivec(b, &a->copies);
    ivec(b, &a->replays);
    ivec(b, &a->candidates);
    ivec(b, &a->intrusions);
    ms_buf_put(b, a->signing, sizeof a->signing);
    ms_buf_put(b, a->cs_gcs, sizeof a->cs_gcs);
    un(b, a->cmd_events.n, 4);
    for (uint32_t i = 0; i < a->cmd_events.n; i++) {
        const ms_cmd_event *e = &a->cmd_events.v[i];
        u8(b, e->kind);
        u8(b, e->target);
        un(b, e->sender, 2);
        un(b, e->msgid, 4);
        un(b, (uint32_t)e->a, 4);
        un(b, (uint32_t)e->b, 4);
        un(b, e->record, 8);
    }
    uint32_t vehicles = 0;
    for (int t = 0; t < 256; t++)
        vehicles += a->commanded[t].senders != NULL;
    un(b, vehicles, 4);
    for (int t = 0; t < 256; t++) {
        const ms_commanded *c = &a->commanded[t];
        if (c->senders == NULL)
            continue;
        u8(b, (unsigned)t);
        un(b, (uint16_t)a->first_commander[t], 2);
        u8(b, c->nshown);
        for (uint32_t i = 0; i < c->nshown; i++) {
            un(b, c->shown_sender[i], 2);
            un(b, c->shown_msgid[i], 4);
        }
        fn(b, &c->fn);
    }
    un(b, a->ctl_events.n, 4);
    for (uint32_t i = 0; i < a->ctl_events.n; i++) {
        const ms_ctl_event *e = &a->ctl_events.v[i];
        u8(b, e->kind);
        u8(b, e->vehicle);
        u8(b, e->sender);
        u8(b, e->holder);
        u8(b, e->flag);
        u8(b, e->why);
        un(b, e->label, 4);
        un(b, e->record, 8);
        un(b, e->since, 8);
        un(b, e->req_record, 8);
        f64(b, e->alt);
        un(b, e->old_len, 2);
        ms_buf_put(b, e->old_mode, e->old_len);
        un(b, e->new_len, 2);
        ms_buf_put(b, e->new_mode, e->new_len);
    }
    un(b, a->episodes.n, 4);
    for (uint32_t i = 0; i < a->episodes.n; i++) {
        const ms_episode *e = &a->episodes.v[i];
        u8(b, e->code);
        u8(b, e->kind);
        un(b, e->sender, 2);
        u8(b, e->flags);
        fn(b, &e->fn);
        f64(b, e->worst);
        for (int k = 0; k < 4; k++)
            f64(b, e->a[k]);
        for (int k = 0; k < 4; k++)
            un(b, (uint64_t)e->n[k], 8);
    }
    return b->failed ? -1 : 0;
}
