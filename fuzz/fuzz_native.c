/* libFuzzer harness for the native core: arbitrary bytes as a capture file, walked by the C record
 * walkers, link/IP/UDP parsers, framer, payload decoder and JSON writer (src/mavscope_native).
 *
 * Input: one selector byte, then the file. Selector bits 0-1: the format (pcap, pcapng, tlog, raw);
 * bit 2: signed frames written natively (no key) or handed back; bit 3: every CRC taken for good (so
 * that mutated payloads reach the decoder and the JSON writer past the CRC check); bits 4-6: a sender
 * preset as seen signing; bit 7: a hostile file: a control byte follows the selector, giving the read
 * window (64 << (c & 7) bytes, so records and resynchronisation scans cross window boundaries) and, in
 * bits 3-5, a file that shrinks after k reads to k/7 of its size (k = 1..6) or whose second read fails
 * (7). The file is read through a memory source, in windows, as the extension reads a file with pread.
 * The batch limit is small so batches end mid-capture. Every JSON line written is checked to be
 * well-formed JSON; every record handed back must hold exactly the file's bytes at its offset (nothing
 * made up), and its notes are read whole, so the sanitizers see every byte the Python glue would. The
 * number and string writers also run directly on the input's bytes, into buffers of exactly the room
 * they claim (MS_DOUBLE_MAX, ms_text_max), so a write past it is a heap overflow for ASan.
 *
 * Every input is then walked a second time by the summary writer (summary.c: the lines of `read FILE`,
 * with the summary table of $MAVSCOPE_FUZZ_SUMMARY and a t0 picked by the input's length: none, the
 * capture's era, 0, or NaN); each line must end in one newline and hold printable ASCII and the route's
 * arrow only. The summary number and string writers (ms_w_g4, ms_w_degrees, ms_w_reltime,
 * ms_w_repr_ascii) run on the input's bytes into buffers of exactly their claimed room too.
 *
 * A third walk fills the export's column buffers (columns.c, in chunks of 1 to 16 frames picked by the
 * input's length, each checked and started over): every frame's wire bytes must be the file's at the
 * offset its column states, its header columns and payload those bytes', every fixed-width column one
 * value per frame, the offsets in order and inside their bytes, each message row its frame's payload
 * zero-extended to the message's length and pointing at a frame of that message, endpoint ids known.
 *
 * Build and run: scripts/fuzz-native.sh SECONDS (docs/native.md). The message table comes from
 * mavscope's default dialect, written by the script to the file named in $MAVSCOPE_FUZZ_TABLE. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "columns.h"
#include "fmt.h"
#include "mavlink.h"
#include "summary.h"
#include "table.h"
#include "walk.h"

static ms_table table;
static ms_summary summary;

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv) {
    (void)argc;
    (void)argv;
    const char *path = getenv("MAVSCOPE_FUZZ_TABLE");
    if (path == NULL) {
        fprintf(stderr, "fuzz_native: set MAVSCOPE_FUZZ_TABLE to the table blob (scripts/fuzz-native.sh)\n");
        abort();
    }
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        perror(path);
        abort();
    }
    static uint8_t blob[1 << 20];
    size_t n = fread(blob, 1, sizeof blob, f);
    fclose(f);
    if (ms_table_parse(&table, blob, n) != 0) {
        fprintf(stderr, "fuzz_native: %s is not a table blob\n", path);
        abort();
    }
    const char *spath = getenv("MAVSCOPE_FUZZ_SUMMARY");
    if (spath == NULL) {
        fprintf(stderr, "fuzz_native: set MAVSCOPE_FUZZ_SUMMARY to the summary blob (scripts/fuzz-native.sh)\n");
        abort();
    }
    f = fopen(spath, "rb");
    if (f == NULL) {
        perror(spath);
        abort();
    }
    n = fread(blob, 1, sizeof blob, f);
    fclose(f);
    if (ms_summary_parse(&summary, &table, blob, n) != 0) {
        fprintf(stderr, "fuzz_native: %s is not a summary blob of this table\n", spath);
        abort();
    }
    return 0;
}

/* A JSON value at *p (end e); depth-limited recursive descent, returns 0 when malformed. */
static int json_value(const char **p, const char *e, int depth);

static int json_string(const char **p, const char *e) {
    const char *s = *p;
    if (s >= e || *s != '"')
        return 0;
    s++;
    while (s < e && *s != '"') {
        unsigned char c = (unsigned char)*s;
        if (c < 0x20)
            return 0;
        if (c == '\\') {
            s++;
            if (s >= e)
                return 0;
            if (*s == 'u') {
                if (e - s < 5)
                    return 0;
                for (int i = 1; i <= 4; i++)
                    if (!strchr("0123456789abcdef", s[i]) || s[i] == '\0')
                        return 0;
                s += 4;
            } else if (!strchr("\"\\/bfnrt", *s) || *s == '\0') {
                return 0;
            }
        }
        s++;
    }
    if (s >= e)
        return 0;
    *p = s + 1;
    return 1;
}

/* The end of the run of ASCII digits at s (s itself when there is none). */
static const char *digits(const char *s, const char *e) {
    while (s < e && *s >= '0' && *s <= '9')
        s++;
    return s;
}

static int json_number(const char **p, const char *e) {
    const char *s = *p;
    if (s < e && *s == '-')
        s++;
    const char *d = s;
    s = digits(s, e);
    if (s == d || (s - d > 1 && *d == '0'))
        return 0;
    if (s < e && *s == '.') {
        d = ++s;
        if ((s = digits(s, e)) == d)
            return 0;
    }
    if (s < e && (*s == 'e' || *s == 'E')) {
        s++;
        if (s < e && (*s == '+' || *s == '-'))
            s++;
        d = s;
        if ((s = digits(s, e)) == d)
            return 0;
    }
    *p = s;
    return 1;
}

static int json_value(const char **p, const char *e, int depth) {
    const char *s = *p;
    if (s >= e || depth > 8)
        return 0;
    if (*s == '{' || *s == '[') {
        const char close = *s == '{' ? '}' : ']';
        s++;
        if (s < e && *s == close) {
            *p = s + 1;
            return 1;
        }
        for (;;) {
            if (close == '}') {
                if (!json_string(&s, e) || s >= e || *s != ':')
                    return 0;
                s++;
            }
            if (!json_value(&s, e, depth + 1) || s >= e)
                return 0;
            if (*s == close) {
                *p = s + 1;
                return 1;
            }
            if (*s != ',')
                return 0;
            s++;
        }
    }
    if (*s == '"')
        return json_string(p, e);
    if ((size_t)(e - s) >= 4 && memcmp(s, "null", 4) == 0) {
        *p = s + 4;
        return 1;
    }
    return json_number(p, e);
}

static void check_lines(const char *text, size_t len) {
    if (len == 0)
        return;
    const char *p = text, *e = text + len;
    while (p < e) {
        const char *nl = memchr(p, '\n', (size_t)(e - p));
        if (nl == NULL || *p != '{')
            abort();
        const char *q = p;
        if (!json_value(&q, nl, 0) || q != nl)
            abort(); /* a malformed JSON line */
        p = nl + 1;
    }
}

/* ms_w_double on doubles and widened floats from the input, ms_w_text on a piece of it, each into a
 * heap buffer of exactly the room it claims */
static void check_writers(const uint8_t *data, size_t size) {
    char *room = malloc(MS_DOUBLE_MAX);
    if (room == NULL)
        return;
    for (size_t i = 0; i + 8 <= size && i < 512; i += 8) {
        uint64_t bits;
        memcpy(&bits, data + i, 8);
        double d;
        memcpy(&d, &bits, 8);
        char *end = ms_w_double(room, d);
        if (end <= room || end > room + 24)
            abort(); /* no double text is longer than 24 bytes */
        float f;
        memcpy(&f, data + i, 4);
        end = ms_w_double(room, (double)f);
        if (end <= room || end > room + 24)
            abort();
    }
    free(room);
    size_t n = size < 256 ? size : 256;
    char *text = malloc(ms_text_max(n));
    if (text == NULL)
        return;
    char *end = ms_w_text(text, data, n);
    if (end - text < 2 || text[0] != '"' || end[-1] != '"')
        abort();
    const char *q = text;
    if (!json_value(&q, end, 0) || q != end)
        abort();
    free(text);
}


/* Summary lines: each ends in its one newline; printable ASCII and the arrow (E2 86 92) only. */
static void check_summary_lines(const char *text, size_t len) {
    if (len && text[len - 1] != '\n')
        abort();
    for (size_t i = 0; i < len; i++) {
        const unsigned char c = (unsigned char)text[i];
        if (c == '\n' || (c >= 0x20 && c < 0x7F))
            continue;
        if (c == 0xE2 && i + 2 < len && (unsigned char)text[i + 1] == 0x86 && (unsigned char)text[i + 2] == 0x92) {
            i += 2;
            continue;
        }
        abort();
    }
}

/* The summary formatters on the input's bytes, into buffers of exactly their claimed room. */
static void check_summary_writers(const uint8_t *data, size_t size) {
    char *g = malloc(MS_G4_MAX), *deg = malloc(MS_DEG_MAX), *rel = malloc(MS_REL_MAX);
    if (g == NULL || deg == NULL || rel == NULL)
        goto done;
    for (size_t i = 0; i + 8 <= size && i < 256; i += 8) {
        uint64_t bits;
        memcpy(&bits, data + i, 8);
        double d;
        memcpy(&d, &bits, 8);
        float f;
        memcpy(&f, data + i, 4);
        if (ms_w_g4(g, d) <= g || ms_w_g4(g, (double)f) <= g)
            abort();
        if (ms_w_degrees(deg, (int64_t)bits, (int)(bits & 1)) <= deg)
            abort();
        (void)ms_w_reltime(rel, d);
        (void)ms_w_reltime(rel, (double)f);
    }
    size_t n = size < 256 ? size : 256;
    char *r = malloc(4 * n + 2);
    if (r != NULL) {
        char *end = ms_w_repr_ascii(r, data, n);
        if (end != NULL && (end - r < 2 || (r[0] != '\'' && r[0] != '"') || end[-1] != r[0]))
            abort();
        free(r);
    }
done:
    free(g);
    free(deg);
    free(rel);
}

static int32_t i32_at(const ms_buf *b, size_t i) {
    int32_t v;
    memcpy(&v, b->data + 4 * i, 4);
    return v;
}

/* An int32 offsets column of the chunk: n + 1 of them from 0, in order, the last the bytes' length. */
static void check_offsets(const ms_buf *at, const ms_buf *bytes, size_t n) {
    if (n == 0)
        return;
    if (at->len != 4 * (n + 1) || i32_at(at, 0) != 0 || (size_t)i32_at(at, n) != bytes->len)
        abort();
    for (size_t i = 0; i < n; i++)
        if (i32_at(at, i) > i32_at(at, i + 1))
            abort();
}

/* A chunk of the column buffers against the file they were read from. */
static void check_columns(const ms_cols *c, const uint8_t *file, size_t size) {
    const size_t n = c->n;
    for (int k = 0; k < MS_NCOLS; k++)
        if (MS_COL_WIDTH[k] && c->col[k].len != n * MS_COL_WIDTH[k])
            abort();
    check_offsets(&c->col[MS_COL_PAYLOAD_AT], &c->col[MS_COL_PAYLOAD], n);
    check_offsets(&c->col[MS_COL_RAW_AT], &c->col[MS_COL_RAW], n);
    size_t rows = 0;
    for (size_t i = 0; i < n; i++) {
        const uint8_t *raw = (const uint8_t *)c->col[MS_COL_RAW].data + i32_at(&c->col[MS_COL_RAW_AT], i);
        const size_t len = (size_t)(i32_at(&c->col[MS_COL_RAW_AT], i + 1) - i32_at(&c->col[MS_COL_RAW_AT], i));
        int64_t off;
        memcpy(&off, c->col[MS_COL_OFFSET].data + 8 * i, 8);
        if (off < 0 || (uint64_t)off > size || len > size - (size_t)off || len < 8 || memcmp(raw, file + off, len))
            abort(); /* a frame's bytes are the file's where its offset says */
        const uint8_t version = (uint8_t)c->col[MS_COL_VERSION].data[i];
        const uint8_t plen = (uint8_t)c->col[MS_COL_LEN].data[i];
        const size_t hlen = version == 2 ? MS_HEADER_V2 : MS_HEADER_V1;
        if (raw[0] != (version == 2 ? MS_STX_V2 : MS_STX_V1) || raw[1] != plen || hlen + plen + 2 > len)
            abort();
        const uint8_t *pay = (const uint8_t *)c->col[MS_COL_PAYLOAD].data + i32_at(&c->col[MS_COL_PAYLOAD_AT], i);
        if (i32_at(&c->col[MS_COL_PAYLOAD_AT], i + 1) - i32_at(&c->col[MS_COL_PAYLOAD_AT], i) != plen ||
            memcmp(pay, raw + hlen, plen))
            abort();
        if ((uint8_t)c->col[MS_COL_SEQ].data[i] != raw[version == 2 ? 4 : 2] ||
            (uint8_t)c->col[MS_COL_SYSID].data[i] != raw[version == 2 ? 5 : 3])
            abort();
        int32_t m, src, dst;
        uint32_t msgid;
        memcpy(&m, c->col[MS_COL_MESSAGE].data + 4 * i, 4);
        memcpy(&msgid, c->col[MS_COL_MSGID].data + 4 * i, 4);
        memcpy(&src, c->col[MS_COL_SRC].data + 4 * i, 4);
        memcpy(&dst, c->col[MS_COL_DST].data + 4 * i, 4);
        if (m < 0 || (size_t)m >= c->table->count || c->table->messages[m].msgid != msgid)
            abort();
        if (src < -1 || dst < -1 || (src >= 0 && (uint32_t)src >= c->nends) || (dst >= 0 && (uint32_t)dst >= c->nends))
            abort();
    }
    for (uint32_t t = 0; t < c->ntouched; t++) {
        const uint32_t k = c->touched[t];
        const ms_msg_rows *r = &c->msgs[k];
        const ms_message *m = &c->table->messages[k];
        if (r->rows.len != (size_t)r->n * m->length || r->frame.len != (size_t)r->n * 4)
            abort();
        for (uint32_t j = 0; j < r->n; j++) {
            uint32_t f;
            memcpy(&f, r->frame.data + 4 * j, 4);
            int32_t fm;
            if (f >= n)
                abort();
            memcpy(&fm, c->col[MS_COL_MESSAGE].data + 4 * f, 4);
            const uint8_t plen = (uint8_t)c->col[MS_COL_LEN].data[f];
            const uint8_t *row = (const uint8_t *)r->rows.data + (size_t)j * m->length;
            const uint8_t *pay = (const uint8_t *)c->col[MS_COL_PAYLOAD].data + i32_at(&c->col[MS_COL_PAYLOAD_AT], f);
            if ((uint32_t)fm != k || plen > m->length || memcmp(row, pay, plen))
                abort();
            for (size_t b = plen; b < m->length; b++)
                if (row[b])
                    abort(); /* zero-extended */
        }
        rows += r->n;
    }
    if (rows != n)
        abort();
}

/* One walk of the file in `mf` (as JSON Lines, or as summary lines with `sum`), checking what comes out. */
static void walk_file(ms_memory_file *mf, const uint8_t *file, size_t n, unsigned sel, unsigned control,
                      const ms_summary *sum, ms_cols *cols) {
    ms_walker w;
    ms_walker_init(&w, ms_memory_source(mf), n, MS_KIND_PCAP + (int)(sel & 3), &table);
    if (sel & 0x80)
        w.reader.window = (size_t)64 << (control & 7);
    w.sign_mode = (sel & 4) ? MS_SIGNED_NOKEY : MS_SIGNED_HANDBACK;
    w.fuzz_any_crc = (sel & 8) != 0;
    if (sum != NULL) {
        static const double T0[4] = {0.0, 1.7e9, 0.0, 0.0};
        w.summary = sum;
        w.has_t0 = (n & 3) != 0;
        w.t0 = (n & 3) == 3 ? __builtin_nan("") : T0[n & 3];
    }
    w.cols = cols;
    const unsigned preset = (sel >> 4) & 7;
    ms_buf out;
    ms_buf_init(&out);
    for (;;) {
        if (preset)
            ms_signer_set(&w, (preset << 8) | 1u); /* a sender seen signing, as Python may add */
        out.len = 0;
        ms_record rec;
        int r = ms_walk(&w, &out, 4096, &rec);
        if (r == MS_WALK_NOMEM)
            break;
        if (cols != NULL) {
            if (out.len != 0)
                abort(); /* column mode writes no text */
            if (r != MS_WALK_FULL || ms_cols_full(cols)) {
                check_columns(cols, file, n);
                ms_cols_restart(cols);
            }
        } else if (sum != NULL) {
            check_summary_lines(out.data, out.len);
        } else {
            check_lines(out.data, out.len);
        }
        if (r == MS_WALK_HANDBACK) {
            /* what the glue reads of a handed-back record: its bytes are the file's at its offset */
            if (rec.len && (rec.offset > n || rec.len > n - rec.offset || memcmp(rec.data, file + rec.offset, rec.len)))
                abort();
            volatile unsigned s = 0;
            for (size_t i = 0; i < rec.notes->n; i++) {
                const ms_note *note = &rec.notes->v[i];
                if (note->msg_off + note->msg_len > rec.notes->text.len)
                    abort();
                for (size_t k = 0; k < note->msg_len; k++)
                    s += (unsigned char)rec.notes->text.data[note->msg_off + k];
            }
            double t;
            (void)ms_record_time(&rec, &t);
            (void)s;
        }
        if (r == MS_WALK_END)
            break;
        w.n_new_signers = 0;
        w.n_new_endpoints = 0;
    }
    ms_buf_free(&out);
    ms_walker_free(&w);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1)
        return 0;
    const unsigned sel = data[0];
    size_t head = 1;
    unsigned control = 0;
    if (sel & 0x80) {
        if (size < 2)
            return 0;
        control = data[1];
        head = 2;
    }
    check_writers(data + head, size - head);
    check_summary_writers(data + head, size - head);
    /* an exactly sized copy: a read past the end of the file is a heap overflow for ASan */
    size_t n = size - head;
    uint8_t *file = malloc(n ? n : 1);
    if (file == NULL)
        return 0;
    memcpy(file, data + head, n);
    for (int pass = 0; pass < 3; pass++) {
        ms_memory_file mf = {file, n, 0, 0, 0, 0};
        if (sel & 0x80) {
            unsigned k = (control >> 3) & 7;
            if (k == 7) {
                mf.fail_at = 2;
            } else if (k) {
                mf.shrink_after = k;
                mf.shrink_to = n * k / 7;
            }
        }
        if (pass < 2) {
            walk_file(&mf, file, n, sel, control, pass ? &summary : NULL, NULL);
            continue;
        }
        ms_cols cols;
        if (ms_cols_init(&cols, &table, 1 + (uint32_t)(n & 15)) != 0)
            break;
        walk_file(&mf, file, n, sel, control, NULL, &cols);
        ms_cols_free(&cols);
    }
    free(file);
    return 0;
}
