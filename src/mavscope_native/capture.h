/* Capture record walkers: pcap, pcapng, tlog and raw files, record by record, read a window at a time.
 *
 * Each walker is a port of the Python reader of the same format (mavscope/capture/): the same records
 * with the same numbers, times, link types, data and notes, including the damage handling
 * (resynchronisation, cut-short files) and the end of a file that shrinks while it is read.
 *
 * Files are never memory-mapped (a mapped file truncated by another process kills the reader with
 * SIGBUS): the bytes come from an ms_source (pread(2) on a file descriptor in the extension, memory in
 * the fuzz harness) into windows of `window` bytes, as capture/reader.py reads them. A short read
 * before the size the file had means the file shrank: `size` drops to where its bytes ended, and the
 * reader ends with the same `record-truncated` note as the Python readers. A failed read ends the
 * reader with the failure record of CaptureReader.failure. No Python API here: the fuzz harness links
 * this file alone. */
#ifndef MAVSCOPE_NATIVE_CAPTURE_H
#define MAVSCOPE_NATIVE_CAPTURE_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"

enum { MS_KIND_PCAP = 1, MS_KIND_PCAPNG = 2, MS_KIND_TLOG = 3, MS_KIND_RAW = 4 };

/* pseudo link types of capture/base.py */
#define MS_LINKTYPE_TLOG (-1)
#define MS_LINKTYPE_RAW (-2)

#define MS_WINDOW (1u << 20) /* capture/reader.py WINDOW */

/* note codes a reader emits (names in ms_note_code_name). MS_NOTE_TIME_CHECK is not a note: it marks
 * where a pcapng record's `time-out-of-range` note goes when its time needs more than C computes exactly
 * (units above 2**64); the glue computes the time with Python ints and writes the note, or drops it. Its
 * message is "INTERFACE". */
enum {
    MS_NOTE_RECORD_TRUNCATED = 1,
    MS_NOTE_RECORD_SNAPPED = 2,
    MS_NOTE_CAPTURE_GARBAGE = 3,
    MS_NOTE_TIME_OUT_OF_RANGE = 4,
    MS_NOTE_TIME_CHECK = 5,
};

typedef struct {
    int code;
    int64_t offset;  /* file offset; every reader note has one */
    size_t msg_off;  /* message text: text.data[msg_off .. msg_off + msg_len) of its ms_notes */
    size_t msg_len;
} ms_note;

typedef struct {
    ms_note *v;
    size_t n, cap;
    ms_buf text;
    int failed;
} ms_notes;

/* How a record's time is known (Python computes it as the comment says; ms_record_time gives it). */
enum {
    MS_TIME_NONE = 0,   /* None */
    MS_TIME_DOUBLE = 1, /* `time` */
    MS_TIME_TICKS = 2,  /* pcapng: ticks / units + tsoffset, units = (2 or 10) ** units_exp */
};

typedef struct {
    uint64_t number;
    int time_kind;
    double time;
    uint64_t ticks;
    int units_pow2;
    int units_exp;
    int64_t tsoffset;
    int64_t linktype;
    const uint8_t *data;   /* the record's bytes, valid until the next ms_reader_next */
    size_t len;
    uint64_t offset;       /* file offset of data[0] */
    uint64_t orig_len;
    const ms_notes *notes; /* owned by the reader, valid until the next call */
} ms_record;

typedef struct {
    uint32_t linktype;
    uint32_t snaplen;
    int units_pow2; /* units = 2 ** exp if set, else 10 ** exp */
    int units_exp;
    int64_t tsoffset;
} ms_iface;

/* Where a reader's bytes come from: `read` puts up to n bytes from file offset `off` into dst and returns
 * how many (fewer only where the file ends), or -1 with an errno value in *err. */
typedef struct {
    int64_t (*read)(void *ctx, uint8_t *dst, size_t n, uint64_t off, int *err);
    void *ctx;
} ms_source;

/* Bytes of the file from `base`: data[0 .. len). */
typedef struct {
    uint8_t *data;
    size_t len, cap;
    uint64_t base;
} ms_window;

typedef struct {
    ms_source src;
    uint64_t size;        /* the file size; drops to where the bytes ended if the file shrinks */
    uint64_t opened_size; /* the size it had when opened */
    size_t window;        /* bytes read at a time (MS_WINDOW; the fuzz harness makes it small) */
    ms_window win;        /* the window records are read from */
    ms_window aux;        /* a second window: resynchronisation scans, short reads */
    int io_errno;         /* a read failed with this errno: the reader ends with its failure record */
    int kind;
    int started;
    int done;
    uint64_t pos;         /* the reader's `pos`: next offset to read */
    uint64_t position;    /* CaptureReader.position, for a progress bar */
    uint64_t n;           /* records yielded */
    ms_notes pending;
    ms_notes out;         /* the notes of the record last returned */
    /* pcap */
    int big;              /* byte order: 1 big-endian (pcap; pcapng: of the current section) */
    int nanosecond;
    uint32_t snaplen;
    uint32_t linktype;
    int header_ok;
    int64_t last_sec;
    /* pcapng */
    ms_iface *ifaces;
    size_t nifaces, capifaces;
    /* tlog */
    int64_t last_ts;
} ms_reader;

const char *ms_note_code_name(int code);

void ms_notes_init(ms_notes *ns);
void ms_notes_free(ms_notes *ns);
void ms_notes_clear(ms_notes *ns);
/* Append a note whose message is printf-formatted. */
void ms_notes_add(ms_notes *ns, int code, int64_t offset, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/* Append every note of `src` to `dst`. */
void ms_notes_extend(ms_notes *dst, const ms_notes *src);

/* Set up a reader of the given kind (detected by the caller as detect.py does) over a file of `size`
 * bytes whose bytes `src` reads. */
void ms_reader_init(ms_reader *r, ms_source src, uint64_t size, int kind);
void ms_reader_free(ms_reader *r);
/* The next record: 1 (rec filled), 0 at the end, -1 when out of memory. */
int ms_reader_next(ms_reader *r, ms_record *rec);
/* A pcap that grows (live capture: records are appended whole): the file now has `size` bytes. The
 * reader goes on after its end only when it ended cleanly there (no note, the last record whole);
 * 0, or -1 when it cannot (then it stays ended). */
int ms_reader_extend(ms_reader *r, uint64_t size);

/* A source over bytes in memory (the fuzz harness, tests): the file is data[0 .. size); after `shrink_after`
 * reads (0: never) it has only `shrink_to` bytes, as a file truncated while it is read; read number
 * `fail_at` (0: none) fails with EIO. */
typedef struct {
    const uint8_t *data;
    uint64_t size;
    unsigned reads;
    unsigned shrink_after;
    uint64_t shrink_to;
    unsigned fail_at;
} ms_memory_file;
ms_source ms_memory_source(ms_memory_file *f);

/* A source reading a file descriptor with pread(2) (never moving its file position); `fd` must outlive it. */
ms_source ms_fd_source(int *fd);

/* The record's time as Python computes it; 0 when it is None, 1 when set, -1 when it cannot be
 * computed exactly in C (pcapng units beyond 2**64: the Python glue computes those). */
int ms_record_time(const ms_record *rec, double *out);

/* Correctly rounded num / den (as Python's int / int); den > 0. */
double ms_div_u64(uint64_t num, uint64_t den);

/* ---- for the format walkers (capture.c) -------------------------------------------------------- */

enum { MS_READ_OK = 0, MS_READ_IO = -1, MS_READ_NOMEM = -2 };

/* CaptureReader.read_at into `w`: up to n bytes from `off`, never past `size` (w->base = off). A short
 * read before `size` means the file shrank: `size` drops to where its bytes ended. MS_READ_IO (errno in
 * r->io_errno) or MS_READ_NOMEM on failure. */
int ms_read_at(ms_reader *r, ms_window *w, uint64_t off, size_t n);
/* CaptureReader.window_at: at least `need` bytes from `off` and a window, where the file has them. */
static inline int ms_window_at(ms_reader *r, ms_window *w, uint64_t off, size_t need) {
    return ms_read_at(r, w, off, need > r->window ? need : r->window);
}
/* read_at into a small caller buffer (n <= 64): how many bytes were read, or a negative MS_READ_*. */
int64_t ms_read_small(ms_reader *r, uint64_t off, size_t n, uint8_t *dst);
/* CaptureReader.shrink_notes, appended to `ns`. */
void ms_shrink_notes(ms_reader *r, ms_notes *ns);
/* End with CaptureReader.failure(number = n + 1, offset, OSError, pending) after a failed read (`rc`
 * MS_READ_IO: 1, rec filled), or -1 when out of memory (MS_READ_NOMEM). */
int ms_reader_fail(ms_reader *r, ms_record *rec, uint64_t offset, int rc, int64_t linktype);
/* Fill `rec` with the reader's next record number and move the pending notes to it. */
void ms_reader_emit(ms_reader *r, ms_record *rec);
void ms_record_set(ms_record *rec, int64_t linktype, const uint8_t *data, size_t len, uint64_t offset,
                   uint64_t orig_len);

/* one per format (capture_pcap.c, capture_pcapng.c, capture_tlog.c) */
int ms_pcap_next(ms_reader *r, ms_record *rec);
int ms_pcapng_next(ms_reader *r, ms_record *rec);
int ms_tlog_next(ms_reader *r, ms_record *rec);

static inline uint16_t ms_le16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static inline uint16_t ms_be16(const uint8_t *p) { return (uint16_t)((p[0] << 8) | p[1]); }
static inline uint32_t ms_le32(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static inline uint32_t ms_be32(const uint8_t *p) {
    return ((uint32_t)p[0] << 24) | ((uint32_t)p[1] << 16) | ((uint32_t)p[2] << 8) | (uint32_t)p[3];
}
static inline uint64_t ms_le64(const uint8_t *p) { return (uint64_t)ms_le32(p) | ((uint64_t)ms_le32(p + 4) << 32); }
static inline uint64_t ms_be64(const uint8_t *p) { return ((uint64_t)ms_be32(p) << 32) | (uint64_t)ms_be32(p + 4); }
static inline uint16_t ms_u16(const uint8_t *p, int big) { return big ? ms_be16(p) : ms_le16(p); }
static inline uint32_t ms_u32(const uint8_t *p, int big) { return big ? ms_be32(p) : ms_le32(p); }

#endif
