/* Capture record walkers: pcap, pcapng, tlog and raw files held in memory, record by record.
 *
 * Each walker mirrors the Python reader of the same format (mavscope/capture/) exactly: the same
 * records with the same numbers, times, link types, data ranges and notes, including the damage
 * handling (resynchronisation, cut-short files). Every read is checked against the end of the buffer.
 * No Python API here: the fuzz harness links this file alone. */
#ifndef MAVSCOPE_NATIVE_CAPTURE_H
#define MAVSCOPE_NATIVE_CAPTURE_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"

enum { MS_KIND_PCAP = 1, MS_KIND_PCAPNG = 2, MS_KIND_TLOG = 3, MS_KIND_RAW = 4 };

/* pseudo link types of capture/base.py */
#define MS_LINKTYPE_TLOG (-1)
#define MS_LINKTYPE_RAW (-2)

/* note codes a reader emits (names in ms_note_code_name) */
enum { MS_NOTE_RECORD_TRUNCATED = 1, MS_NOTE_RECORD_SNAPPED = 2, MS_NOTE_CAPTURE_GARBAGE = 3 };

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
    size_t start;      /* data: buf[start .. start + len) */
    size_t len;
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

typedef struct {
    const uint8_t *buf;
    size_t size;
    int kind;
    int done;
    size_t pos;      /* next offset to read */
    uint64_t n;      /* records yielded */
    ms_notes pending;
    ms_notes out;    /* the notes of the record last returned */
    /* pcap */
    int big;         /* byte order: 1 big-endian */
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

/* Set up a reader over buf[0..size) of the given kind (detected by the caller as detect.py does). */
void ms_reader_init(ms_reader *r, const uint8_t *buf, size_t size, int kind);
void ms_reader_free(ms_reader *r);
/* The next record: 1 (rec filled), 0 at the end, -1 when out of memory. */
int ms_reader_next(ms_reader *r, ms_record *rec);

/* The record's time as Python computes it; 0 when it is None, 1 when set, -1 when it cannot be
 * computed exactly in C (pcapng units beyond 2**64: the Python glue computes those). */
int ms_record_time(const ms_record *rec, double *out);

/* Correctly rounded num / den (as Python's int / int); den > 0. */
double ms_div_u64(uint64_t num, uint64_t den);

/* internal, one per format (capture_pcap.c, capture_pcapng.c, capture_tlog.c) */
int ms_pcap_init(ms_reader *r);
int ms_pcap_next(ms_reader *r, ms_record *rec);
int ms_pcapng_init(ms_reader *r);
int ms_pcapng_next(ms_reader *r, ms_record *rec);
int ms_tlog_next(ms_reader *r, ms_record *rec);
/* move the pending notes to the record being returned */
void ms_reader_emit(ms_reader *r, ms_record *rec);

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
