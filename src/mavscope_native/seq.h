/* One sender's (and channel's) MAVLink sequence numbers: a port of SeqTracker (analysis/sequence.py),
 * step for step. `missing` is Python's insertion-ordered dict seq -> gap: a doubly linked list over the
 * 256 sequence numbers (allocated with the first gap); `gaps` are the first GAPS_KEPT large gaps (a large
 * gap beyond those is counted but, as in Python, never looked at again). No Python API here. */
#ifndef MAVSCOPE_NATIVE_SEQ_H
#define MAVSCOPE_NATIVE_SEQ_H

#include <stddef.h>
#include <stdint.h>

#define MS_RAW_MAX 300 /* the longest frame: 12 + 255 + 2 + 13 = 282 bytes */

enum { MS_STEP_FIRST, MS_STEP_NEXT, MS_STEP_GAP, MS_STEP_DUPLICATE, MS_STEP_UNCHANGED, MS_STEP_LATE, MS_STEP_RESET };

typedef struct {
    uint64_t record;
    uint8_t before, after;
    uint8_t size, remaining;
    uint8_t shared; /* of `remaining`, numbers another id on the channel used */
} ms_gap;

typedef struct {
    uint8_t present[32];
    uint8_t taken[32]; /* TAKEN: another id on the channel used the number */
    int8_t gap[256];   /* index into the tracker's gaps, -1: a small gap (or one not kept) */
    uint8_t next[256], prev[256];
    int16_t head, tail; /* -1: empty */
} ms_missing;

typedef struct {
    int16_t last; /* -1: no frame yet */
    uint8_t run_seq;
    uint8_t ngaps;
    int32_t run;
    int64_t lost, duplicates, repeats, unchanged, reordered, resets, position, newest;
    uint64_t large_gaps;
    ms_missing *missing;
    ms_gap *gaps;
    uint8_t *last_raw; /* MS_RAW_MAX bytes once a frame's bytes were given */
    uint16_t last_raw_len;
    uint8_t has_last_raw;
    int64_t shared, full_steps, gap_steps, first_full; /* first_full: -1, none */
    int32_t partner; /* -1: none */
} ms_seq;

typedef struct {
    int gap_min, gaps_kept, reset_run;
} ms_seq_rules;

void ms_seq_init(ms_seq *s);
void ms_seq_free(ms_seq *s);
/* Feed one sequence number (`raw`: the frame's bytes, or NULL as Python's raw=None; `taken`, `partner`: of a
 * jump ahead, the first numbers skipped another id on the channel used, and its sender). Returns MS_STEP_*,
 * or -1 when memory ran out. */
int ms_seq_feed(ms_seq *s, const ms_seq_rules *r, unsigned seq, uint64_t record, const uint8_t *raw, size_t raw_len,
                unsigned taken, int32_t partner);

#endif
