/* The native `stats` accumulator: StatsBuilder (analysis/stats.py) and the expert detectors that look at
 * every frame (analysis/expert.py SequenceAnomalies, CommandSources, ReplayedCommands, UnsignedCommands;
 * analysis/control.py ControlSources with vehicles.py Systems and mavlink/modes.py; analysis/gnss.py
 * GnssAnomalies), ported step for step, fed one frame at a time in capture order: by the walker for the
 * records it takes (walk.c) and by the glue for the frames of handed-back records (module.c, from
 * mavscope/native_stats.py), so that both go into this one state. BadCrcBursts and KeyLeaks stay in
 * Python: only handed-back frames can have a bad CRC or be SETUP_SIGNING.
 *
 * What the Python classes keep in dicts is kept here in insertion order too (findings and rows come out
 * in that order before their stable sorts). Every table grown from input is capped (MS_CAP_*, and the
 * Python analyses' own caps from the plan); when a cap that Python does not have is reached, `full` is
 * set, nothing more is accumulated and the caller runs the pure path instead. At the end ms_acc_dump
 * writes the whole state (layout below) for native_stats.py, which rebuilds the Python objects and lets
 * their own code write the findings' sentences and the JSON. No Python API here. */
#ifndef MAVSCOPE_NATIVE_ACC_H
#define MAVSCOPE_NATIVE_ACC_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"
#include "plan.h"
#include "seq.h"

#define MS_CAP_STRINGS (1u << 20)  /* endpoint texts */
#define MS_CAP_STREAMS (1u << 16)  /* (sysid, compid, message): past the plan's MS_K_MAX_STREAMS, unfollowed */
#define MS_CAP_LINKS (1u << 16)    /* (sysid, compid): every sender there can be */
#define MS_CAP_CHANNELS (1u << 17) /* sequence trackers per sender and channel: each sender's first and
                                      the plan's MS_K_MAX_EXTRA (4,096) more */
#define MS_CAP_CONVS (1u << 16)    /* past the plan's MS_K_MAX_CONVERSATIONS, unfollowed */
#define MS_CAP_PAIRS (1u << 18)    /* counted names (the sequence findings': also the plan's MS_K_MAX_NAMED) */
#define MS_CAP_ENDS (1u << 22)     /* a link's endpoints, a conversation's systems */
#define MS_CAP_ITEMS (1u << 18)    /* events (3 per sender at most), findings in the making, reported keys */
#define MS_FN_MAX 64               /* frame numbers kept per finding (framelist.MAX_FRAMES, checked) */
#define MS_MODE_MAX 320            /* a flight mode's name */

enum { MS_CRC_OK, MS_CRC_BAD, MS_CRC_UNCHECKED, MS_CRC_TRUNCATED, MS_CRC_N };
enum { MS_SIG_UNSIGNED, MS_SIG_VALID, MS_SIG_INVALID, MS_SIG_NOKEY, MS_SIG_REPLAY, MS_SIG_TRUNCATED, MS_SIG_N };
enum { MS_TR_UDP, MS_TR_TCP, MS_TR_TLOG, MS_TR_RAW, MS_TR_N };

/* One frame, as StatsBuilder.add and Expert.add read it. */
typedef struct {
    uint64_t record;
    int has_time;
    double time;
    int transport;  /* MS_TR_* */
    int32_t src, dst; /* ms_acc_intern ids of the endpoints' text, -1: None */
    const uint8_t *raw;
    size_t raw_len;
    int version;
    unsigned seq, sysid, compid;
    uint32_t msgid;
    int known;         /* msgdef is not None */
    int crc;           /* MS_CRC_* */
    int sig;           /* MS_SIG_*: signature_verdict(frame) */
    int has_signature; /* frame.signature is not None */
    const uint8_t *payload; /* plaintext_payload(frame); NULL: nothing to decode */
    size_t payload_len;
} ms_acc_frame;

typedef struct {
    uint64_t count;
    uint32_t n;
    uint64_t nums[MS_FN_MAX];
} ms_fnums;

/* open addressing u64 -> u32 (no deletion) */
typedef struct {
    uint64_t *keys;
    uint32_t *vals; /* UINT32_MAX: empty */
    uint32_t cap, n;
} ms_map;

typedef struct {
    uint64_t key; /* sysid << 32 | compid << 24 | msgid */
    uint64_t count, bytes;
    double first, last, width;
    uint8_t has_time, has_rates;
    uint32_t nbins;
    uint64_t *bins;
} ms_stream;

typedef struct {
    uint64_t received, bytes, v1, v2;
    uint64_t crc[MS_CRC_N], sig[MS_SIG_N];
    double first, last;
    uint16_t sender;
    uint8_t has_time;
    int32_t chan_head, chan_tail; /* the sender's channels, in order */
    uint32_t nchan;
    int32_t events[3];  /* SequenceAnomalies (duplicate, late, unchanged): index in ev, or -1 */
    int32_t copies, replays; /* ReplayedCommands: index in named, or -1 */
    ms_seq replay_seq;  /* ReplayedCommands.trackers[link] */
} ms_link;

typedef struct {
    int32_t src, dst; /* -1: "" (no endpoint); MS_SHARED both: the shared channel ("*", "*") */
    int32_t next;
    int32_t counter;  /* index in counters (SeqTracker.channel), -1: none (the shared channel) */
    int32_t slot;     /* SeqTracker.slot */
    uint64_t at;      /* SeqTracker.at */
    uint16_t sender;
    int32_t held; /* ReplayedCommands.held: index in helds, or -1 */
    ms_seq seq;
} ms_chan;

#define MS_VEC(T) struct { T *v; uint32_t n, cap; }

/* replays.ReplayedCommands: the copies of one channel judged by the frames after them (_Held): the first
 * MS_LISTED of a run with their frames, the others counted per message (ahead_more, behind_more) */
#define MS_LISTED 25 /* replays.LISTED (framelist.MAX_FRAMES // 2) */
#define MS_MORE_MAX 64 /* messages counted past MS_LISTED in one run (COMMANDING has 19): past it, `full` */
typedef struct {
    uint64_t order, orig, copy;
    uint32_t label;
} ms_held_copy;
typedef struct {
    uint64_t count, order; /* copies past MS_LISTED, the order of the first (ahead: unused) */
    uint32_t label;
} ms_held_more;
typedef MS_VEC(ms_held_copy) ms_held_copies;
typedef MS_VEC(ms_held_more) ms_held_mores;
typedef struct {
    uint16_t sender;
    uint8_t ahead_seq;
    ms_held_copies ahead, behind; /* the ahead copies' `order` unused */
    ms_held_mores ahead_more, behind_more;
} ms_held;
#define MS_SHARED (-2)

/* sequence.ChannelCounter: one channel's frames, whoever sent them */
typedef struct {
    uint64_t frames;
    int32_t ring[MS_RING]; /* index in chans, -1 */
    uint16_t senders[MS_RING];
    uint32_t next;
} ms_counter;

typedef struct {
    int32_t a, b; /* intern ids (the transport's name or "" where there is no endpoint) */
    uint8_t transport, has_time;
    uint64_t frames_ab, frames_ba, bytes_ab, bytes_ba;
    double first, last;
} ms_conv;

typedef struct {
    uint32_t owner; /* link, conversation, ... */
    uint32_t value;
    uint64_t count;
} ms_pair;

typedef struct {
    ms_pair *v;
    uint32_t n, cap, limit; /* limit: MS_CAP_PAIRS or MS_CAP_ENDS */
    ms_map index; /* owner << 32 | value -> position in v */
} ms_pairs;

typedef struct {
    uint16_t sender;
    uint8_t what; /* 0 duplicate, 1 late, 2 unchanged */
    ms_fnums fn;
} ms_event;

/* a finding in the making with counted names (ReplayedCommands, UnsignedCommands, intrusions) */
typedef struct {
    uint32_t key;
    ms_fnums fn;
    int64_t holder;
    uint64_t since;
} ms_named;

/* CommandSources.commanded: the new commanders of one vehicle (analysis/commanders.py Commanded) */
typedef struct {
    uint8_t *senders; /* [8192] bitmap of sysid << 8 | compid; NULL until the first */
    uint32_t nshown;
    uint16_t shown_sender[MS_SHOWN_MAX];
    uint32_t shown_msgid[MS_SHOWN_MAX];
    ms_fnums fn; /* the first frame of each; fn.count: how many */
} ms_commanded;

/* CommandSources.out */
typedef struct {
    uint8_t kind; /* 1 unexpected-command-source, 2 command-without-heartbeat */
    uint8_t target;
    uint16_t sender;
    uint32_t msgid;
    int32_t a, b; /* src: the frame's endpoint and the known one */
    uint64_t record;
} ms_cmd_event;

typedef struct {
    uint8_t type, autopilot, base_mode, system_status;
    uint32_t custom_mode;
} ms_hb;

typedef struct {
    uint8_t exists, armed;
    uint8_t has_holder, has_request, has_landed, has_alt, has_disarm;
    uint8_t holder;
    uint64_t since;
    /* request: (sender, label, frame, time, mode asked for) */
    uint8_t req_sender, req_has_time;
    uint32_t req_label;
    uint64_t req_record;
    double req_time;
    uint16_t req_mode_len, mode_len;
    char req_mode[MS_MODE_MAX], mode[MS_MODE_MAX];
    int64_t landed;
    uint8_t landed_has_t, alt_has_t, disarm_has_t, disarm_sender;
    double landed_t, alt, alt_t, disarm_t;
    uint64_t disarm_record;
} ms_control;

/* ControlSources.out */
typedef struct {
    uint8_t kind; /* 0 unexpected-mission-clear, 1 unexpected-mode-change, 2 in-flight-disarm */
    uint8_t vehicle, sender, holder, flag; /* clear: MISSION_CLEAR_ALL; disarm: by a command */
    uint8_t why;  /* disarm: 0 the altitude, 1 the landed state (in `label`) */
    uint32_t label;
    uint64_t record, since, req_record;
    double alt;
    uint16_t old_len, new_len;
    char old_mode[MS_MODE_MAX], new_mode[MS_MODE_MAX];
} ms_ctl_event;

enum { MS_G_GPI, MS_G_GPS_RAW, MS_G_GPS2_RAW, MS_G_SYSTEM_TIME, MS_G_EKF, MS_G_EST, MS_G_N };
enum { MS_GC_JUMP, MS_GC_COLLAPSE, MS_GC_EKF, MS_GC_TIME };
#define MS_EPISODE_TEXT 0x80

typedef struct {
    double t, lat, lon, speed;
    uint64_t record;
    uint8_t has, has_speed;
} ms_fix;

typedef struct {
    ms_fix fixes[3];
    double clocks[MS_G_N];
    uint8_t has_clock[MS_G_N];
    uint8_t has_speed, ekf_good, ekf_alarm, has_utc, utc_has_t, has_boot;
    uint8_t has_good[3], collapsed[3];
    double good_t[3];
    int64_t good_sats[3];
    double speed, utc_u, utc_b, utc_t, boot_s;
    uint64_t utc_record;
} ms_gsender;

typedef struct {
    uint8_t code, kind; /* MS_GC_*, MS_G_* of the message */
    uint16_t sender;
    uint8_t flags;      /* MS_EPISODE_TEXT: a sentence was made (a size above -1.0 was seen); ekf: 1 glitch,
                           2 position lost, 4 ratio; time: 1 against capture time, 2 a GPS time; collapse: 1 nsat */
    ms_fnums fn;
    double worst;
    double a[4];
    int64_t n[4];
} ms_episode;

typedef MS_VEC(int32_t) ms_ivec;

typedef struct {
    const ms_plan *plan;
    int full; /* a cap was reached: the caller runs the pure path */
    uint64_t unfollowed_streams, unfollowed_convs; /* frames beyond MS_K_MAX_STREAMS, MS_K_MAX_CONVERSATIONS */
    ms_seq_rules rules;
    /* totals */
    uint64_t total, nbytes, crc[MS_CRC_N], sig[MS_SIG_N], v1, v2;
    uint8_t has_first;
    double first, last;
    /* interned strings */
    char *text;
    size_t text_len, text_cap;
    uint32_t *str_off, *str_len;
    uint32_t nstr;
    int32_t *str_slots;
    uint32_t str_cap;
    /* StatsBuilder */
    MS_VEC(ms_stream) streams;
    ms_map stream_index;
    int32_t last_stream;
    MS_VEC(ms_link) links;
    int32_t *link_of; /* [65536] sender -> index in links, -1 */
    MS_VEC(ms_chan) chans;
    uint32_t extra; /* SeqChannels.extra */
    MS_VEC(ms_counter) counters;
    ms_map counter_index; /* (src, dst) -> index in counters (SeqChannels.counters) */
    MS_VEC(ms_conv) convs;
    ms_map conv_index;
    ms_pairs link_endpoints, conv_systems;
    /* SequenceAnomalies */
    MS_VEC(ms_event) ev;
    ms_pairs ev_labels; /* (event index, label) -> count: the messages of each event's frames */
    /* ReplayedCommands: copies and replays (names: label -> count), the copies seen (LRU) */
    MS_VEC(ms_named) named; /* shared by ReplayedCommands, UnsignedCommands and intrusions */
    ms_pairs names;         /* (named index, label) -> count */
    ms_ivec copies, replays;
    struct ms_seen *seen;
    MS_VEC(ms_held) helds;
    uint64_t held_order; /* ReplayedCommands.order */
    /* UnsignedCommands */
    uint8_t signing[32];
    ms_ivec candidates;
    ms_map candidate_index;
    /* CommandSources */
    uint8_t heartbeat_seen[8192], cs_gcs[32];
    int32_t first_commander[256];
    ms_commanded commanded[256];
    ms_map reported, cs_endpoints;
    MS_VEC(ms_cmd_event) cmd_events;
    /* Systems and ControlSources */
    int32_t *hb_of; /* [65536] sender -> index in hbs, -1 */
    MS_VEC(ms_hb) hbs;
    uint8_t sys_gcs[32];
    int32_t vehicle_addr[256]; /* Systems.vehicles: sysid -> sender, -1 */
    uint8_t vehicle_order[256];
    uint32_t nvehicles;
    ms_control control[256];
    ms_ivec intrusions;
    ms_map intrusion_index;
    MS_VEC(ms_ctl_event) ctl_events;
    /* GnssAnomalies */
    MS_VEC(ms_gsender) gsenders;
    ms_map gsender_index;
    MS_VEC(ms_episode) episodes;
    ms_map episode_index;
    /* the last record's endpoints (ms_acc_record) */
    int32_t rec_src, rec_dst, rec_conv;
    int rec_forward;
} ms_acc;

/* 0, or -1 when memory runs out */
int ms_acc_init(ms_acc *a, const ms_plan *plan);
void ms_acc_free(ms_acc *a);
/* The id of a string (endpoint text), interned; -1: out of memory, -2: the table is full (`full` set). */
int32_t ms_acc_intern(ms_acc *a, const char *s, size_t n);
/* Accumulate one frame: 0, 1 when `full` (nothing more is accumulated), -1 out of memory. */
int ms_acc_add(ms_acc *a, const ms_acc_frame *f);
/* The frames of one clean record the walker took (walk.c): `frames` holds (position, size) pairs into d. */
int ms_acc_record(ms_acc *a, uint64_t number, int has_time, double t, int udp, const char *src, size_t src_len,
                  const char *dst, size_t dst_len, const uint8_t *d, const uint32_t *frames, size_t count);
/* The whole state (native_stats.py reads it): 0, or -1 when memory ran out. */
int ms_acc_dump(ms_acc *a, ms_buf *out); /* judges what is held first (ms_expert_finish) */

/* helpers shared by acc.c, expert.c, control.c, gnss.c */
int ms_map_get(const ms_map *m, uint64_t key, uint32_t *val);
int ms_map_put(ms_map *m, uint64_t key, uint32_t val);
void ms_map_free(ms_map *m);
void ms_fn_add(ms_fnums *fn, uint64_t number, uint32_t limit);
int ms_vec_grow(void **v, uint32_t *cap, uint32_t need, size_t item, uint32_t limit);
/* the (owner, value) pair's count + 1 (new pairs at the end); -1 nomem, 1 full */
int ms_pairs_count(ms_pairs *p, uint32_t owner, uint32_t value, uint64_t add);
/* a new ms_named entry for `key` (an index in a->named), or -1 nomem / -2 full */
int32_t ms_named_new(ms_acc *a, uint32_t key);
/* The entry *slot (made and appended to `order` when -1) counts `records` and one `label`: 0, -1 nomem,
 * 1 full */
int ms_count_named(ms_acc *a, int32_t *slot, ms_ivec *order, uint32_t key, const uint64_t *records, int nrec,
                   uint32_t label);

#define MS_VGROW(a, vec, limit)                                                                              \
    ms_vec_grow((void **)&(vec).v, &(vec).cap, (vec).n + 1, sizeof *(vec).v, (limit))

/* expert.c, control.c, gnss.c: the detectors' part of one frame */
typedef struct {
    int has; /* 0: absent (or the frame has no decoded fields) */
    int is_float;
    int64_t i;
    double d; /* the value as a Python float would be: float(i) for integers */
} ms_val;

ms_val ms_get(const ms_acc_frame *f, const ms_plan_msg *pm, int slot);
/* channels.c: SeqChannels.tracker (NULL: a cap filled, `full` set, or memory ran out) and .feed (MS_STEP_*,
 * -1 nomem) */
ms_chan *ms_channel(ms_acc *a, ms_link *lk, int32_t src, int32_t dst);
int ms_channel_feed(ms_acc *a, ms_chan *ch, const ms_acc_frame *f);
int ms_expert_add(ms_acc *a, const ms_acc_frame *f, ms_link *lk, ms_chan *ch, int step);
/* ReplayedCommands.finish: the copies still held judged (0, -1 out of memory, 1 full) */
int ms_expert_finish(ms_acc *a);
int ms_control_add(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm);
int ms_gnss_add(ms_acc *a, const ms_acc_frame *f, const ms_plan_msg *pm);
void ms_seen_free(struct ms_seen *s);
void ms_held_free(ms_held *h); /* its copies' arrays */
size_t ms_mode_name(const ms_plan *p, unsigned autopilot, unsigned type, unsigned base, uint64_t custom, char *out);

#endif
