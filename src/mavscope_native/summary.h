/* Summary lines (`mavscope read FILE`, the text output), byte-identical to output/text.py summary_line.
 *
 * What a message's Info column shows is compiled once in Python (mavscope/native_summary.py, from the
 * same `summary_plan` of fields/summary.py the pure path uses: SUMMARY_FIELDS, enum names, degE7 as
 * degrees) and handed to C as one byte string, parallel to the layout table (table.h):
 *
 *   "MSSM", u32 version (3), u32 message count (= the layout table's, in its order), then per message:
 *   u32 msgid, u8 flags (bit 0: Python only; bit 1: a u16 field index follows the name, of a scalar integer
 *   field of at most 32 bits whose value not 0 leaves the line to Python: STATUSTEXT's `id`, a chunk of a
 *   long text), u8 item count, u16 name length, the name (UTF-8), [u16 that field index];
 *   u16 param1 field index (0xFFFF: none; a command message's param1, named after its command's <param>
 *   and never infinite, as semantics.command_param_name requires), u16 command field index (0xFFFF: not a
 *   command message; an integer of at most 32 bits), u32 command count, per command (sorted by value):
 *   i64 value, u8 flags (MS_CMD_*: Python names it; bits), u8 labelled (bit i - 1: the MAV_CMD entry
 *   labels param i), u32 entry count and entries (as below, sorted as signed values: the whole number
 *   param1 holds -> its name, or the names of the bits it holds, as Enum.flags_of);
 *   per item: u16 field index (into the layout table's fields), u8 how (MS_HOW_*), u8 param (1..7: the
 *   command parameter the field is, left out when its command does not label it and it holds nothing,
 *   semantics.param_shown; 0: none), u8 label length, the label ("name="), u32 entry count, then per entry
 *   (an enum's names, sorted by value as the field's type compares: signed or unsigned): u64 value, u8
 *   name length, the name.
 *
 * ms_summary_parse checks every length, every field index, that entries are strictly sorted, and that no
 * text holds a newline (a line is one line). */
#ifndef MAVSCOPE_NATIVE_SUMMARY_H
#define MAVSCOPE_NATIVE_SUMMARY_H

#include <stddef.h>
#include <stdint.h>

#include "buf.h"
#include "table.h"

enum { MS_HOW_PLAIN = 0, MS_HOW_ENUM = 1, MS_HOW_DEGREES = 2 };

typedef struct {
    uint64_t value;
    const char *name;
    uint8_t name_len;
} ms_enum_entry;

typedef struct {
    uint16_t field;
    uint8_t how;
    uint8_t param; /* 1..7: the command parameter this field is (a number); 0: none */
    uint8_t label_len;
    const char *label;
    uint32_t nentries;
    ms_enum_entry *entries;
} ms_sitem;

enum { MS_CMD_PYTHON = 1, MS_CMD_BITS = 2 };

typedef struct {
    int64_t value;
    uint8_t flags;    /* MS_CMD_PYTHON: Python names param1; MS_CMD_BITS: the entries are bits (flags_of) */
    uint8_t labelled; /* bit i - 1: the MAV_CMD entry labels param i */
    uint32_t nentries;
    ms_enum_entry *entries;
} ms_command;

#define MS_NO_FIELD 0xFFFF

typedef struct {
    uint8_t python_only;
    uint16_t python_if; /* field index: a frame where it is not 0 is Python's (flags bit 1); MS_NO_FIELD */
    uint16_t param1;  /* field index, or MS_NO_FIELD */
    uint16_t command; /* field index of a command message's command, or MS_NO_FIELD */
    uint32_t ncommands;
    ms_command *commands;
    uint8_t nitems;
    uint16_t name_len;
    const char *name;
    ms_sitem *items;
    size_t info_max; /* the longest Info text the writer makes for this message (signature suffix included) */
} ms_smessage;

typedef struct {
    const ms_table *table;
    ms_smessage *messages; /* parallel to table->messages */
    size_t count;
    uint8_t *blob;         /* a copy of the blob: names and labels point into it */
} ms_summary;

int ms_summary_parse(ms_summary *s, const ms_table *t, const uint8_t *blob, size_t len);
void ms_summary_free(ms_summary *s);

static inline const ms_smessage *ms_summary_get(const ms_summary *s, const ms_message *m) {
    return &s->messages[m - s->table->messages];
}

/* Text writers, exactly as Python formats (for the writer and the tests); each returns the end. */
#define MS_DEG_MAX 48 /* f"{v / 1e7:.7f}" of a 64-bit integer */
char *ms_w_degrees(char *p, int64_t v, int is_unsigned);
#define MS_REL_MAX 40 /* f"{t:11.6f}" for |t| < 1e15 */
/* f"{t:11.6f}"; NULL when |t| >= 1e15 or t is not finite (the caller hands the record back) */
char *ms_w_reltime(char *p, double t);
/* repr() of bytes decoded as Python's char_text would (up to the first NUL); NULL when a byte is not
 * ASCII (printable non-ASCII characters need Unicode tables: the caller hands the record back). */
char *ms_w_repr_ascii(char *p, const uint8_t *s, size_t n);

#define MS_PREFIX_MAX 256
/* " {time - t0:11.6f} {route:<34} " of one record (the time column "-" without a time or t0; the route
 * "src → dst", or "tlog" when src is NULL) into `out` (MS_PREFIX_MAX bytes); its length, or 0 when the
 * record must go to the Python path (a time span C does not format). */
size_t ms_summary_prefix(char *out, int has_time, double t, int has_t0, double t0, const char *src, size_t src_len,
                         const char *dst, size_t dst_len);
/* The summary lines of one record's frames (`frames`: (position, size) pairs into d, as the walk's scan
 * found them): each the frame number ("12", "12.2"), `prefix`, the header columns and the Info text.
 * 0 when written, 1 when the record must go to the Python path (out->len may then hold some of its
 * lines: the caller resets it), -1 when memory ran out. */
int ms_write_summary(const ms_summary *s, ms_buf *out, uint64_t number, const char *prefix, size_t prefix_len,
                     const uint8_t *d, const uint32_t *frames, const uint8_t *bad, size_t count);

#endif
