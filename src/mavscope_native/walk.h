/* The native walk: capture records -> finished JSON Lines, or records handed back to Python.
 *
 * A record is written here only when the Python path would give it nothing but clean frames: no
 * reader note, a UDP datagram (or a tlog entry) that is a run of frames with known message ids, good
 * CRCs, no unknown or encryption flags, no length mismatch, not SETUP_SIGNING or
 * MAVSCOPE_KEY_EXCHANGE, no unsigned frame from a sender seen signing, and signed frames only when no
 * signing key is configured (the `no-key` verdict) or, with keys, when the frame is the next of a known
 * stream under the key that verified it last (the `valid` verdict, MS_SIGNED_VERIFY). Records with nothing for MAVLink (not IP, not
 * UDP/TCP, an empty datagram) are consumed silently, as Python does. Everything else is handed back
 * whole, in capture order, for the Python pipeline.
 *
 * The state both paths share is explicit: `signers` (the security stage's signed_senders) and the
 * endpoints that carried valid MAVLink (the Dissector's mavlink_endpoints). The glue loads `signers`
 * from the Python set before each batch and pushes back what the batch added (`new_signers`,
 * `new_endpoints`); Python changes them only while handling a handed-back record, between batches. What
 * else the Python dissector keeps from a record (its number and time, the frame index, the end of a run
 * of tlog text entries) it learns from `Dissector.passed`, told of the records walked by each batch.
 * The signing state (signing.h) is not copied at all: the walker and the Python verifier use the same
 * ms_signing, the walker during a batch, Python between batches. */
#ifndef MAVSCOPE_NATIVE_WALK_H
#define MAVSCOPE_NATIVE_WALK_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"
#include "capture.h"
#include "columns.h"
#include "netlayers.h"
#include "signing.h"
#include "summary.h"
#include "table.h"

/* Signed frames: handed back; written with the no-key verdict (no signing key configured); or judged
 * here against the shared signing state (MS_SIGNED_VERIFY: a known stream, its key's MAC, a newer
 * timestamp is written as `valid`; anything else is handed back for the Python verifier). */
enum { MS_SIGNED_HANDBACK = 0, MS_SIGNED_NOKEY = 1, MS_SIGNED_VERIFY = 2 };
/* a frame's note the walker writes itself: none, an unsigned or a MAVLink 1 frame of a sender that signs */
enum { MS_FNOTE_NONE = 0, MS_FNOTE_UNSIGNED = MS_NOTE_UNSIGNED, MS_FNOTE_V1 = MS_NOTE_V1 }; /* columns.h's codes */
#define MS_NOTE_TPL_MAX 256 /* bytes of one template piece */
enum { MS_TPL_UNSIGNED = 0, MS_TPL_V1 = 1, MS_TPL_BAD_CRC = 2, MS_NOTE_TPLS = 3 };
enum { MS_WALK_NOMEM = -1, MS_WALK_END = 0, MS_WALK_FULL = 1, MS_WALK_HANDBACK = 2 };

typedef struct {
    uint32_t stream; /* ms_sign_stream() */
    uint32_t key;
    uint64_t last;   /* the timestamp the record would make the stream's last accepted one */
} ms_sign_pending;

#define MS_ENDPOINT_TEXT 64

typedef struct {
    ms_reader reader;
    const ms_table *table;
    int sign_mode;              /* MS_SIGNED_*, set by the glue before each batch */
    ms_signing *signing;        /* MS_SIGNED_VERIFY: the signing state shared with Python (signing.h) */
    const ms_summary *summary;  /* non-NULL: summary lines (summary.h) instead of JSON Lines */
    int has_t0;                 /* summary lines: relative times count from t0 (the first record's time) */
    double t0;
    ms_cols *cols;              /* non-NULL: column mode (columns.h, the export) instead of JSON Lines; the
                                   walk also stops once the columns hold their limit of frames */
    int fuzz_any_crc;           /* the fuzz harness only: take every CRC for good, so that mutated
                                   payloads reach the decoder and the JSON writer (never set by the glue) */
    int fuzz_any_mac;           /* the fuzz harness only: take every MAC for good (MS_SIGNED_VERIFY), so that
                                   mutated signed frames reach the `valid` writer (never set by the glue) */
    uint8_t signers[8192];      /* bit sysid << 8 | compid: senders seen signing */
    uint16_t *new_signers;      /* added by this batch */
    size_t n_new_signers, cap_new_signers;
    ms_endpoint *new_endpoints; /* sources of valid MAVLink first seen by this batch */
    size_t n_new_endpoints, cap_new_endpoints;
    size_t endpoint_room;       /* new endpoints Python's set still takes (MS_MAX_ENDPOINTS less its size, set by
                                   the glue before each batch): past it, a record from an unknown source is
                                   handed back (Dissector._learn says the give-up) */
    ms_endpoint *waiting;       /* UDP destinations whose receivers are in a frame where their last datagram
                                   ended (Python's Dissector.receivers): their next datagram is handed back */
    size_t n_waiting, cap_waiting;
    int hand_back_all;          /* every record is handed back: Python's TCP reassembly waits on a hole, which any
                                   record's time may end (Dissector.receivers.hand_back, read per Walker.next) */
    ms_endpoint *seen;          /* endpoints already reported (open addressing, `used` marks a slot) */
    uint8_t *seen_used;
    size_t nseen, capseen;
    uint32_t *frames;           /* scratch: (position, size) of the frames of the current record */
    size_t cap_frames;
    uint8_t *fnote;             /* scratch: per frame of the current record its note (MS_FNOTE_*) */
    size_t cap_fnote;
    char *note_tpl[MS_NOTE_TPLS][4]; /* the JSON of the notes the walker writes itself, each cut where its values
                                   go (mavscope.native.walk.note_templates): unsigned-in-signed-stream and
                                   v1-in-signed-stream (name, sender, offset), bad-crc (CRC, offset); NULL:
                                   frames needing them are handed back */
    size_t note_tpl_len[MS_NOTE_TPLS][4];
    uint8_t *fbad;              /* scratch: per frame of the current record, 1 when its CRC is bad */
    size_t cap_fbad;
    const uint16_t *ports;      /* MAVLink's well-known UDP ports (Dissector's MAVLINK_PORTS): a datagram to or
                                   from one is taken for MAVLink without a valid frame */
    size_t nports;
    uint16_t *tentative;        /* scratch: senders the current record would add */
    size_t cap_tentative;
    uint32_t *sig_keys;         /* scratch, MS_SIGNED_VERIFY: per frame of the current record the key slot
                                   that verified it (MS_SIGN_NO_KEY: unsigned) */
    size_t cap_sig_keys;
    ms_sign_pending *pending;   /* scratch, MS_SIGNED_VERIFY: the streams the current record would advance */
    size_t n_pending, cap_pending;
    ms_endpoint last_noted;     /* the endpoint note_endpoint saw last (most records repeat it) */
    int have_last_noted;
    ms_endpoint text_key[2];    /* the last two endpoints formatted, and their text */
    char text[2][MS_ENDPOINT_TEXT];
    int text_len[2];
    ms_record walked;           /* the last record walked natively by the current ms_walk call (what the
                                   Python pipeline's Dissector.passed is told) */
    uint64_t n_walked;          /* records walked natively by the current ms_walk call */
    int64_t py_index;           /* what Dissector._index would hold after the records walked natively by
                                   the current call (Python's general scanner sets it: records with a
                                   MAVLink 1 frame); -1: unchanged */
    uint64_t records_native, records_handed_back, frames_native; /* counters */
    /* A raw byte stream (MS_KIND_RAW) with `raw_native` (set by the glue when given the RawLink: every walk, column
     * mode too): its clean stretches are written here (or put into the columns: ms_cols_raw), and only the
     * pieces around damage are handed back, to Python's framer for the stream (walk.c walk_raw says where a
     * piece is cut). Without it every chunk is handed back whole. */
    int raw_native;
    int64_t raw_held;           /* set by the glue before each ms_walk (Python's RawLink.held): -1 when the
                                   stream's framer is idle, else how many of the last bytes it was fed it has
                                   still to read (it goes on from there) */
    uint64_t raw_frames;        /* the stream's frames numbered so far by either engine (RawLink.frames: loaded by
                                   the glue before each ms_walk, given back after it) */
    ms_record raw_rec;          /* the chunk being walked; its data stays valid until the next ms_reader_next */
    int raw_have;               /* raw_rec has bytes from raw_pos on that are neither written nor handed back */
    size_t raw_pos;
    uint8_t *carry;             /* the bytes Python's framer had still to read at the end of the chunk before (at
                                   most MS_RAW_CARRY): a piece's cut is judged from where its framer goes on */
    size_t carry_len, cap_carry;
    uint64_t carry_base;        /* file offset of carry[0]; carry ends where raw_rec begins */
    int carry_ok;               /* carry holds every byte Python's framer has to read from before raw_rec */
} ms_walker;

#define MS_RAW_CARRY 65536

int ms_walker_init(ms_walker *w, ms_source src, uint64_t size, int kind, const ms_table *table);
/* Make room for n waiting destinations (w->waiting, w->n_waiting set by the caller): 0, or -1 (no memory). */
int ms_walker_waiting_room(ms_walker *w, size_t n);
/* Sources of valid MAVLink Python's Dissector remembers at most (its MAX_MAVLINK_ENDPOINTS). */
#define MS_MAX_ENDPOINTS 16384
/* Take `e` for reported (the glue loads Python's full set once): 0, or -1 out of memory. */
int ms_walker_remember_endpoint(ms_walker *w, const ms_endpoint *e);
void ms_walker_free(ms_walker *w);

/* Walk records, appending JSON lines to `out`, until `out` holds at least `limit` bytes (MS_WALK_FULL),
 * a record must be handed back (MS_WALK_HANDBACK, *rec is that record; its data and notes stay valid
 * until the next call), or the capture ends (MS_WALK_END). MS_WALK_NOMEM when memory ran out. The
 * records walked natively before a handed-back one: `n_walked`, the last of them `walked`. */
int ms_walk(ms_walker *w, ms_buf *out, size_t limit, ms_record *rec);

static inline int ms_signer_has(const ms_walker *w, unsigned sender) {
    return (w->signers[sender >> 3] >> (sender & 7)) & 1;
}
static inline void ms_signer_set(ms_walker *w, unsigned sender) {
    w->signers[sender >> 3] |= (uint8_t)(1u << (sender & 7));
}

#endif
