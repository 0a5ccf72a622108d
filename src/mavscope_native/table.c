#include "table.h"

#include "blob.h"

#include "fmt.h"

#include <stdlib.h>
#include <string.h>

static const size_t TYPE_SIZE[] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8, 1};
/* the room the writer of one element needs: u8 255, i8 -128, u16, i16, u32, i32, u64, i64, floats (fmt.h) */
static const size_t TEXT_MAX[] = {0, 3, 4, 5, 6, 10, 11, 20, 20, MS_DOUBLE_MAX, MS_DOUBLE_MAX, 0};

/* Copy the next n bytes of text into the arena (followed by MS_TEXT_PAD zero bytes). */
static const char *take_text(ms_cursor *c, size_t n, char *arena, size_t *used, size_t cap) {
    if (c->bad || (size_t)(c->end - c->p) < n || n == 0 || cap - *used < n + MS_TEXT_PAD) {
        c->bad = 1;
        return NULL;
    }
    char *s = arena + *used;
    memcpy(s, c->p, n);
    memset(s + n, 0, MS_TEXT_PAD);
    *used += n + MS_TEXT_PAD;
    c->p += n;
    return s;
}

void ms_table_free(ms_table *t) {
    if (t->messages != NULL)
        for (size_t i = 0; i < t->count; i++)
            free(t->messages[i].fields);
    free(t->messages);
    free(t->slots);
    free(t->text);
    memset(t, 0, sizeof *t);
}

int ms_table_parse(ms_table *t, const uint8_t *blob, size_t len) {
    memset(t, 0, sizeof *t);
    ms_cursor c = {blob, blob + len, 0};
    if (len < 12 || memcmp(blob, "MSNT", 4) != 0)
        return -1;
    c.p += 4;
    if (ms_take(&c, 4) != 1)
        return -1;
    uint32_t count = (uint32_t)ms_take(&c, 4);
    if (count > 1u << 20 || (size_t)count * 10 > len)
        return -1;
    /* every text is at least 1 byte of the blob and each takes MS_TEXT_PAD more in the arena */
    const size_t arena_cap = len * (1 + MS_TEXT_PAD);
    size_t used = 0;
    t->text = malloc(arena_cap);
    t->messages = calloc(count ? count : 1, sizeof *t->messages);
    size_t nslots = 16;
    while (nslots < 2 * (size_t)count)
        nslots *= 2;
    t->slots = malloc(nslots * sizeof *t->slots);
    if (t->text == NULL || t->messages == NULL || t->slots == NULL)
        goto fail;
    for (size_t i = 0; i < nslots; i++)
        t->slots[i] = -1;
    t->nslots = nslots;
    for (uint32_t m = 0; m < count; m++) {
        ms_message *msg = &t->messages[m];
        t->count = m + 1;
        msg->msgid = (uint32_t)ms_take(&c, 4);
        msg->crc_extra = (uint8_t)ms_take(&c, 1);
        msg->length = (uint8_t)ms_take(&c, 1);
        msg->base_length = (uint8_t)ms_take(&c, 1);
        msg->python_only = (uint8_t)(ms_take(&c, 1) & 1);
        msg->nfields = (uint16_t)ms_take(&c, 2);
        msg->name_len = (uint16_t)ms_take(&c, 2);
        msg->name = take_text(&c, msg->name_len, t->text, &used, arena_cap);
        if (c.bad || msg->msgid > 0xFFFFFF || msg->base_length > msg->length || msg->nfields > 255)
            goto fail;
        msg->fields = calloc(msg->nfields ? msg->nfields : 1, sizeof *msg->fields);
        if (msg->fields == NULL)
            goto fail;
        msg->json_max = 2; /* {} */
        for (uint16_t f = 0; f < msg->nfields; f++) {
            ms_field *fd = &msg->fields[f];
            fd->type = (uint8_t)ms_take(&c, 1);
            fd->count = (uint8_t)ms_take(&c, 1);
            fd->offset = (uint8_t)ms_take(&c, 1);
            fd->key_len = (uint8_t)ms_take(&c, 1);
            fd->key = take_text(&c, fd->key_len, t->text, &used, arena_cap);
            unsigned base = fd->type & 0x7F;
            if (c.bad || base < MS_T_U8 || base > MS_T_CHAR || fd->count == 0)
                goto fail;
            if ((fd->type & MS_T_ARRAY) && base == MS_T_CHAR)
                goto fail;
            if (!(fd->type & MS_T_ARRAY) && base != MS_T_CHAR && fd->count != 1)
                goto fail;
            if ((size_t)fd->offset + TYPE_SIZE[base] * fd->count > msg->length)
                goto fail;
            size_t value;
            if (base == MS_T_CHAR)
                msg->has_char = 1;
            if (base == MS_T_CHAR)
                value = 6 * (size_t)fd->count + 2; /* ms_text_max */
            else if (fd->type & MS_T_ARRAY)
                value = 2 + (size_t)fd->count * (TEXT_MAX[base] + 1);
            else
                value = TEXT_MAX[base];
            msg->json_max += 1 + fd->key_len + value;
        }
        size_t i = (msg->msgid * 2654435761u) & (nslots - 1);
        while (t->slots[i] >= 0) {
            if (t->messages[t->slots[i]].msgid == msg->msgid)
                goto fail; /* duplicate id */
            i = (i + 1) & (nslots - 1);
        }
        t->slots[i] = (int32_t)m;
    }
    if (c.p != c.end)
        goto fail;
    return 0;
fail:
    ms_table_free(t);
    return -1;
}
