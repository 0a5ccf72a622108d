/* Reading the blobs Python hands over (the layout table, table.c; the summary table, summary.c): a
 * cursor that turns every read past the end into a sticky `bad` flag and zeros. */
#ifndef MAVSCOPE_NATIVE_BLOB_H
#define MAVSCOPE_NATIVE_BLOB_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    const uint8_t *p;
    const uint8_t *end;
    int bad;
} ms_cursor;

/* The next n (<= 8) bytes as a little-endian number, or 0 and `bad` when fewer are left. */
static inline uint64_t ms_take(ms_cursor *c, size_t n) {
    if (c->bad || (size_t)(c->end - c->p) < n) {
        c->bad = 1;
        return 0;
    }
    uint64_t v = 0;
    for (size_t i = 0; i < n; i++)
        v |= (uint64_t)c->p[i] << (8 * i);
    c->p += n;
    return v;
}

#endif
