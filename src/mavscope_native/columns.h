/* Column buffers for the export's native batch source (mavscope/export/native.py).
 *
 * In column mode the walker (walk.c) fills these buffers instead of writing JSON Lines, for the same clean
 * records (walk.h says which); every other record is handed back, as in the JSON walk. Per frame, one
 * fixed-width value in each frame column (MS_COL_*), little-endian as the machine's native order (the
 * Python side views them with numpy and pyarrow without copying); the frame's payload bytes and its whole
 * wire bytes, each as an Arrow-style binary column (int32 offsets, n + 1 of them, and the bytes). Per
 * message of the layout table (table.h), the payloads of its frames zero-extended to the message's full
 * length, one row after the other (Python reads them through a numpy dtype compiled from the dialect), and
 * for each row the position of its frame in the frame columns. Sources and destinations are endpoint ids;
 * the endpoints behind new ids are listed for Python (`endpoints`), which names them.
 *
 * Nothing here allocates without bounds: the walk stops taking records once `limit` frames are held
 * (ms_cols_full), the caller takes the buffers (the module hands their memory to Python) and the next
 * chunk starts empty; the endpoint map starts over past MS_COLS_ENDPOINTS entries (at a take, so that ids
 * are stable within a chunk). Allocation failure sets `failed`; the walk then reports out of memory. */
#ifndef MAVSCOPE_NATIVE_COLUMNS_H
#define MAVSCOPE_NATIVE_COLUMNS_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"
#include "capture.h"
#include "netlayers.h"
#include "table.h"

enum {
    MS_COL_RECORD,     /* int64: record number */
    MS_COL_INDEX,      /* int32: 1-based position of the frame in its record */
    MS_COL_TIME,       /* double: capture time (0.0 where TIME_OK is 0) */
    MS_COL_TIME_OK,    /* uint8: 1 when the record has a time */
    MS_COL_TRANSPORT,  /* uint8: MS_TRANSPORT_* */
    MS_COL_SRC,        /* int32: endpoint id, -1 for none (tlog, raw) */
    MS_COL_DST,        /* int32 */
    MS_COL_VERSION,    /* uint8: 1 or 2 */
    MS_COL_LEN,        /* uint8: LEN */
    MS_COL_IFLAGS,     /* uint8 */
    MS_COL_CFLAGS,     /* uint8 */
    MS_COL_SEQ,        /* uint8 */
    MS_COL_SYSID,      /* uint8 */
    MS_COL_COMPID,     /* uint8 */
    MS_COL_MSGID,      /* uint32 */
    MS_COL_MESSAGE,    /* int32: the message's position in the layout table */
    MS_COL_CRC,        /* uint16: the CRC as sent */
    MS_COL_SIG_LINK,   /* uint8: signature link id (0 for an unsigned frame) */
    MS_COL_SIG_TIME,   /* int64: signature timestamp, 48 bits (0 for an unsigned frame) */
    MS_COL_SIG_VALUE,  /* 6 bytes: the signature (zeros for an unsigned frame) */
    MS_COL_OFFSET,     /* int64: file offset of the STX byte */
    MS_COL_PAYLOAD_AT, /* int32 offsets (n + 1) into PAYLOAD */
    MS_COL_PAYLOAD,    /* bytes: the payloads as on the wire */
    MS_COL_RAW_AT,     /* int32 offsets (n + 1) into RAW */
    MS_COL_RAW,        /* bytes: the frames as on the wire (header to signature) */
    MS_COL_SIZE,       /* uint16: the frame's size in bytes (header to signature) */
    MS_COL_NOTE,       /* uint8: the frame's notes (MS_NOTE_*: 0 for a clean frame; only with `notes`) */
    MS_NCOLS,
};

/* the columns' names as Python knows them (module.c exports them as COLUMN_NAMES, in this order) */
extern const char *const MS_COL_NAMES[MS_NCOLS];
/* bytes per frame of each fixed-width column (0: the offsets and bytes of PAYLOAD and RAW) */
extern const uint8_t MS_COL_WIDTH[MS_NCOLS];

enum { MS_TRANSPORT_UDP = 1, MS_TRANSPORT_TLOG = 2, MS_TRANSPORT_RAW = 3 };

/* the note column's bits (a frame the walk takes with notes: walk.c, as its JSON Lines walk writes them):
 * an unsigned MAVLink 2 or a MAVLink 1 frame of a sender that signs, and a bad CRC */
enum { MS_NOTE_UNSIGNED = 1, MS_NOTE_V1 = 2, MS_NOTE_BAD_CRC = 4 };

/* the columns an index_only chunk fills (bit k: MS_COL_k) */
#define MS_INDEX_COLUMNS                                                                                     \
    ((1u << MS_COL_RECORD) | (1u << MS_COL_INDEX) | (1u << MS_COL_TIME) | (1u << MS_COL_TIME_OK) |           \
     (1u << MS_COL_TRANSPORT) | (1u << MS_COL_SRC) | (1u << MS_COL_DST) | (1u << MS_COL_IFLAGS) |            \
     (1u << MS_COL_SEQ) | (1u << MS_COL_SYSID) | (1u << MS_COL_COMPID) | (1u << MS_COL_MSGID) |              \
     (1u << MS_COL_OFFSET) | (1u << MS_COL_SIZE))

#define MS_COLS_ENDPOINTS 65536 /* endpoint ids remembered; past that the map starts over at a take */
#define MS_COLS_MAX_FRAMES (1u << 22) /* a chunk never holds more (its byte offsets fit int32) */

typedef struct {
    ms_buf rows;   /* `length` bytes per row */
    ms_buf frame;  /* uint32 per row: its frame's position in the frame columns */
    uint32_t n;
    int listed;    /* in `touched` */
} ms_msg_rows;

typedef struct {
    const ms_table *table;
    uint32_t limit;        /* the walk stops once this many frames are held */
    uint32_t n;            /* frames held */
    ms_buf col[MS_NCOLS];
    ms_msg_rows *msgs;     /* one per message of the table */
    uint32_t *touched;     /* positions of the messages with rows, in the order they got their first */
    uint32_t ntouched;
    /* endpoints: id -> endpoint, and an open-addressing map endpoint -> id + 1 (0: empty slot) */
    ms_endpoint *ends;
    uint32_t nends, capends;
    uint32_t *slots;
    uint32_t nslots;
    uint32_t first_new;    /* ids from here on are new since the last take */
    int reset;             /* the map started over at the last take: ids before it mean nothing now */
    ms_endpoint recent[8]; /* endpoints looked up lately, by a cheap hash of port and address (the map's */
    uint32_t recent_id[8]; /* FNV hash costs a fifth of an index walk); valid while recent_ok, until the */
    uint8_t recent_ok[8];  /* map starts over */
    int notes;             /* the walk takes frames with the notes of MS_NOTE_* (with their code in NOTE)
                              instead of handing their records back */
    int index_only;        /* the TUI's index (mavscope/browse/native.py): only MS_INDEX_COLUMNS are filled,
                              no payloads, wire bytes, signatures or message rows (those columns stay empty) */
    int failed;
} ms_cols;

/* 0, or -1 when memory runs out. `limit` frames per chunk (at least 1, at most MS_COLS_MAX_FRAMES). */
int ms_cols_init(ms_cols *c, const ms_table *table, uint32_t limit);
void ms_cols_free(ms_cols *c);

static inline int ms_cols_full(const ms_cols *c) {
    return c->n >= c->limit;
}

/* Append the `count` frames of a record the walk takes (their (position, size) pairs in `frames`, within
 * d[0..n); per frame its MS_NOTE_* bits in `notes`, NULL for none); `udp` NULL for a tlog entry. 0, or -1
 * when memory runs out. A frame with a bad CRC gets no message row (its fields are no one's). */
int ms_cols_record(ms_cols *c, const ms_record *rec, const uint8_t *d, const uint32_t *frames, const uint8_t *notes,
                   size_t count, int has_time, double t, const ms_udp *udp);

/* Append `count` frames of a raw byte stream (walk.c raw_run), as the Python pipeline has them
 * (Dissector._stream): each a record of its own numbered on from `first` (record `first + i`, index 1), no
 * time, transport MS_TRANSPORT_RAW, no endpoints (-1); file offset `base + frames[2 * i]`. 0, or -1 when
 * memory runs out. */
int ms_cols_raw(ms_cols *c, const uint8_t *d, uint64_t base, const uint32_t *frames, const uint8_t *notes,
                size_t count, uint64_t first);

/* Start the next chunk: the buffers are emptied (the caller took their memory: it zeroed each ms_buf
 * it took), message rows forgotten, endpoint ids since `first_new` no longer new; the endpoint map starts
 * over when it grew past MS_COLS_ENDPOINTS (`reset` tells). */
void ms_cols_restart(ms_cols *c);

#endif
