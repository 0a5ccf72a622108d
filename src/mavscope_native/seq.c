#include "seq.h"

#include <stdlib.h>
#include <string.h>

#define LATE_WINDOW 128 /* sequence.LATE_WINDOW (the plan checks it) */

void ms_seq_init(ms_seq *s) {
    memset(s, 0, sizeof *s);
    s->last = -1;
    s->first_full = -1;
    s->partner = -1;
}

void ms_seq_free(ms_seq *s) {
    free(s->missing);
    free(s->gaps);
    free(s->last_raw);
    ms_seq_init(s);
}

static int has(const ms_missing *m, unsigned k) {
    return (m->present[k >> 3] >> (k & 7)) & 1;
}

/* Remove k (present) from the list. */
static void unlink_key(ms_missing *m, unsigned k) {
    int p = m->head == (int16_t)k ? -1 : m->prev[k];
    int n = m->tail == (int16_t)k ? -1 : m->next[k];
    if (p >= 0)
        m->next[p] = (uint8_t)n;
    else
        m->head = (int16_t)n;
    if (n >= 0)
        m->prev[n] = (uint8_t)p;
    else
        m->tail = (int16_t)p;
    m->present[k >> 3] &= (uint8_t)~(1u << (k & 7));
}

/* dict.pop(k, None) then d[k] = gap: k goes to the end. */
static void push_back(ms_missing *m, unsigned k, int gap, int taken) {
    if (has(m, k))
        unlink_key(m, k);
    m->present[k >> 3] |= (uint8_t)(1u << (k & 7));
    if (taken)
        m->taken[k >> 3] |= (uint8_t)(1u << (k & 7));
    else
        m->taken[k >> 3] &= (uint8_t)~(1u << (k & 7));
    m->gap[k] = (int8_t)gap;
    if (m->tail < 0) {
        m->head = m->tail = (int16_t)k;
    } else {
        m->next[m->tail] = (uint8_t)k;
        m->prev[k] = (uint8_t)m->tail;
        m->tail = (int16_t)k;
    }
}

static void clear(ms_missing *m) {
    memset(m->present, 0, sizeof m->present);
    m->head = m->tail = -1;
}

static void advance(ms_seq *s, unsigned seq, int d) {
    s->last = (int16_t)seq;
    s->newest += d;
    s->position = s->newest;
    ms_missing *m = s->missing;
    if (m == NULL)
        return;
    while (m->head >= 0) {
        unsigned k = (unsigned)m->head;
        if (((seq - k) & 0xFF) < LATE_WINDOW)
            break;
        unlink_key(m, k);
    }
}

int ms_seq_feed(ms_seq *s, const ms_seq_rules *r, unsigned seq, uint64_t record, const uint8_t *raw, size_t raw_len,
                unsigned taken, int32_t partner) {
    /* previous, self.last_raw = self.last_raw, raw; `changed`: raw is not None and previous is not None
     * and raw != previous (only looked at when the number repeats) */
    unsigned d = s->last < 0 ? 0 : (seq - (unsigned)s->last) & 0xFF;
    int changed = 0;
    if (raw != NULL) {
        if (raw_len > MS_RAW_MAX)
            raw_len = MS_RAW_MAX; /* never: frames are at most 282 bytes */
        if (s->last_raw == NULL) {
            s->last_raw = malloc(MS_RAW_MAX);
            if (s->last_raw == NULL)
                return -1;
        } else if (s->has_last_raw && s->last >= 0 && d == 0) {
            changed = s->last_raw_len != raw_len || memcmp(s->last_raw, raw, raw_len) != 0;
        }
        memcpy(s->last_raw, raw, raw_len);
        s->last_raw_len = (uint16_t)raw_len;
        s->has_last_raw = 1;
    } else {
        s->has_last_raw = 0;
    }
    if (s->last < 0) {
        s->last = (int16_t)seq;
        return MS_STEP_FIRST;
    }
    int32_t behind_run = s->run;
    s->run = 0;
    if (d == 1) {
        advance(s, seq, 1);
        return MS_STEP_NEXT;
    }
    if (d == 0) {
        s->position = s->newest;
        if (changed) {
            s->unchanged++;
            return MS_STEP_UNCHANGED;
        }
        s->duplicates++;
        s->repeats++;
        return MS_STEP_DUPLICATE;
    }
    if (d < LATE_WINDOW) {
        int gap = -1;
        if ((int)d - 1 >= r->gap_min) {
            s->large_gaps++;
            if (s->ngaps < r->gaps_kept) {
                if (s->gaps == NULL && (s->gaps = malloc((size_t)r->gaps_kept * sizeof *s->gaps)) == NULL)
                    return -1;
                ms_gap *g = &s->gaps[s->ngaps];
                g->record = record;
                g->before = (uint8_t)s->last;
                g->after = (uint8_t)seq;
                g->size = g->remaining = (uint8_t)(d - 1);
                g->shared = (uint8_t)taken;
                gap = s->ngaps++;
            }
        }
        if (d > 1) {
            if (s->missing == NULL) {
                if ((s->missing = malloc(sizeof *s->missing)) == NULL)
                    return -1;
                clear(s->missing);
            }
            for (unsigned k = 1; k < d; k++)
                push_back(s->missing, ((unsigned)s->last + k) & 0xFF, gap, k <= taken);
        }
        s->gap_steps++;
        if (taken) {
            s->shared += taken;
            if (taken == d - 1) {
                s->full_steps++;
                if (s->first_full < 0) {
                    s->partner = partner;
                    s->first_full = (int64_t)record;
                }
            }
        }
        s->lost += (int64_t)d - 1;
        advance(s, seq, (int)d);
        return MS_STEP_GAP;
    }
    s->position = s->newest - (256 - (int64_t)d);
    if (s->missing != NULL && has(s->missing, seq)) {
        int gap = s->missing->gap[seq];
        int was_taken = (s->missing->taken[seq >> 3] >> (seq & 7)) & 1;
        unlink_key(s->missing, seq);
        if (was_taken)
            s->shared--;
        if (gap >= 0) {
            s->gaps[gap].remaining--;
            if (was_taken)
                s->gaps[gap].shared--;
        }
        s->lost--;
        s->reordered++;
        return MS_STEP_LATE;
    }
    s->duplicates++;
    s->run = behind_run && seq == (((unsigned)s->run_seq + 1) & 0xFF) ? behind_run + 1 : 1;
    s->run_seq = (uint8_t)seq;
    if (s->run >= r->reset_run) {
        s->duplicates -= s->run;
        s->resets++;
        s->run = 0;
        if (s->missing != NULL)
            clear(s->missing);
        advance(s, seq, 256);
        return MS_STEP_RESET;
    }
    return MS_STEP_DUPLICATE;
}
