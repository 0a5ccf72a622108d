#include "buf.h"

#include <stdlib.h>

void ms_buf_init(ms_buf *b) {
    b->data = NULL;
    b->len = 0;
    b->cap = 0;
    b->failed = 0;
}

void ms_buf_free(ms_buf *b) {
    free(b->data);
    ms_buf_init(b);
}

int ms_buf_grow(ms_buf *b, size_t need) {
    if (b->failed)
        return -1;
    if (need > SIZE_MAX / 2 - b->len) {
        b->failed = 1;
        return -1;
    }
    size_t want = b->len + need;
    size_t cap = b->cap ? b->cap : 256;
    while (cap < want)
        cap *= 2;
    char *p = realloc(b->data, cap);
    if (p == NULL) {
        b->failed = 1;
        return -1;
    }
    b->data = p;
    b->cap = cap;
    return 0;
}
