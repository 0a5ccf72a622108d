/* A growable byte buffer the native core writes into (JSON text, note messages).
 *
 * Every write goes through ms_buf_room(), which grows the buffer before anything is written, so no
 * write can run past the end. Allocation failure sets `failed` and turns later writes into no-ops:
 * the caller checks `failed` once per batch. */
#ifndef MAVSCOPE_NATIVE_BUF_H
#define MAVSCOPE_NATIVE_BUF_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    char *data;
    size_t len;
    size_t cap;
    int failed; /* an allocation failed: the content is incomplete */
} ms_buf;

void ms_buf_init(ms_buf *b);
void ms_buf_free(ms_buf *b);
/* Grow so that `need` more bytes fit; 0 on success, -1 (and `failed` set) when out of memory. */
int ms_buf_grow(ms_buf *b, size_t need);

/* A pointer where `need` bytes may be written, or NULL when out of memory. Advance `len` after writing. */
static inline char *ms_buf_room(ms_buf *b, size_t need) {
    if ((b->cap - b->len < need || b->data == NULL) && ms_buf_grow(b, need) != 0)
        return NULL;
    return b->data + b->len;
}

static inline void ms_buf_put(ms_buf *b, const void *src, size_t n) {
    char *p = ms_buf_room(b, n);
    if (p == NULL)
        return;
    if (n)
        memcpy(p, src, n);
    b->len += n;
}

#define MS_BUF_LIT(b, lit) ms_buf_put((b), (lit), sizeof(lit) - 1)

static inline void ms_buf_byte(ms_buf *b, char c) {
    char *p = ms_buf_room(b, 1);
    if (p == NULL)
        return;
    *p = c;
    b->len += 1;
}

#endif
