/* The message layout table: compiled once in Python from mavscope's Dialect (MessageDef/FieldDef,
 * themselves from pymavlink's XML parser) by mavscope/native.py and handed to C as one byte string.
 *
 * Blob layout (little-endian): "MSNT", u32 version (1), u32 message count, then per message:
 *   u32 msgid, u8 crc_extra, u8 length, u8 base_length, u8 flags (bit 0: Python only), u16 field count,
 *   u16 name length, the message name as JSON text (quotes included);
 *   per field: u8 type (MS_T_*, | MS_T_ARRAY for a list), u8 count (elements; a char field: its bytes),
 *   u8 offset in the padded payload, u8 key length, the key as JSON text with its colon ("name":).
 * ms_table_parse checks every length and that every field lies inside the message. */
#ifndef MAVSCOPE_NATIVE_TABLE_H
#define MAVSCOPE_NATIVE_TABLE_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

enum {
    MS_T_U8 = 1, MS_T_I8, MS_T_U16, MS_T_I16, MS_T_U32, MS_T_I32, MS_T_U64, MS_T_I64, MS_T_F32, MS_T_F64,
    MS_T_CHAR, /* a string: its bytes up to the first NUL, UTF-8 with backslashreplace */
    MS_T_ARRAY = 0x80,
};

/* Every name and key is followed by this many readable bytes, so a text of at most MS_TEXT_PAD bytes
 * can be copied with one fixed-size memcpy of MS_TEXT_PAD bytes (the writer leaves room for it). */
#define MS_TEXT_PAD 32

static inline char *ms_w_padded(char *p, const char *text, size_t len) {
    if (len <= MS_TEXT_PAD)
        memcpy(p, text, MS_TEXT_PAD);
    else
        memcpy(p, text, len);
    return p + len;
}

typedef struct {
    uint8_t type;
    uint8_t count;
    uint8_t offset;
    uint8_t key_len;
    const char *key;
} ms_field;

typedef struct {
    uint32_t msgid;
    uint8_t crc_extra;
    uint8_t length;
    uint8_t base_length;
    uint8_t python_only; /* frames of this message always go to the Python path */
    uint8_t has_char;    /* a field is a char array (ms_char_tail) */
    uint16_t nfields;
    uint16_t name_len;
    const char *name;
    ms_field *fields;
    size_t json_max; /* the longest "fields" object ms_w_fields can write for this message */
} ms_message;

typedef struct {
    ms_message *messages;
    size_t count;
    int32_t *slots;  /* open addressing: index into messages or -1 */
    size_t nslots;   /* a power of two */
    char *text;      /* the names and keys, each followed by MS_TEXT_PAD zero bytes (fixed-size copies) */
} ms_table;

/* The length of a char array's string: its bytes up to the first NUL (or all `n`). */
static inline size_t ms_char_len(const uint8_t *v, size_t n) {
    const uint8_t *z = memchr(v, 0, n);
    return z == NULL ? n : (size_t)(z - v);
}

/* Whether a char array of `m` in `payload` (its first `len` bytes; the rest are zero) holds a byte that is
 * not NUL after the NUL that ends its string (mavlink/framing.py's `char-after-nul` note: Python's). */
static inline int ms_char_tail(const ms_message *m, const uint8_t *payload, size_t len) {
    for (uint16_t i = 0; i < m->nfields; i++) {
        const ms_field *f = &m->fields[i];
        if ((f->type & 0x7F) != MS_T_CHAR || f->offset >= len)
            continue;
        size_t n = f->count;
        if (n > len - f->offset)
            n = len - f->offset;
        const uint8_t *v = payload + f->offset;
        for (size_t k = ms_char_len(v, n); k < n; k++)
            if (v[k])
                return 1;
    }
    return 0;
}

/* 0 on success, -1 when the blob is malformed or memory runs out (the table is left empty). */
int ms_table_parse(ms_table *t, const uint8_t *blob, size_t len);
void ms_table_free(ms_table *t);

static inline const ms_message *ms_table_get(const ms_table *t, uint32_t msgid) {
    if (t->nslots == 0)
        return NULL;
    size_t mask = t->nslots - 1;
    size_t i = (msgid * 2654435761u) & mask;
    for (;;) {
        int32_t k = t->slots[i];
        if (k < 0)
            return NULL;
        if (t->messages[k].msgid == msgid)
            return &t->messages[k];
        i = (i + 1) & mask;
    }
}

#endif
