/* libFuzzer harness for the native core: arbitrary bytes as a capture file, walked by the C record
 * walkers, link/IP/UDP parsers, framer, payload decoder and JSON writer (src/mavscope_native).
 *
 * Input: one selector byte, then the file. Selector bits 0-1: the format (pcap, pcapng, tlog, raw);
 * bit 2: signed frames written natively (no key) or handed back; bit 3: every CRC taken for good (so
 * that mutated payloads reach the decoder and the JSON writer past the CRC check); bits 4-6: a sender
 * preset as seen signing; bit 7: a hostile file: a control byte follows the selector, giving the read
 * window (64 << (c & 7) bytes, so records and resynchronisation scans cross window boundaries) and, in
 * bits 3-5, a file that shrinks after k reads to k/7 of its size (k = 1..6) or whose second read fails
 * (7); bit 6: the Dissector's set of MAVLink sources nearly full (room for 1 to 3, by the input's length),
 * so that records from sources beyond it are handed back, else room for MS_MAX_ENDPOINTS as the glue
 * gives it before each batch (the sources the walks learn counted against it). The file is read through a memory source, in windows, as the extension reads a file with pread.
 * The batch limit is small so batches end mid-capture. Every JSON line written is checked to be
 * well-formed JSON; every record handed back must hold exactly the file's bytes at its offset (nothing
 * made up), and its notes are read whole, so the sanitizers see every byte the Python glue would. The
 * number and string writers also run directly on the input's bytes, into buffers of exactly the room
 * they claim (MS_DOUBLE_MAX, ms_text_max), so a write past it is a heap overflow for ASan.
 *
 * Every input is then walked a second time by the summary writer (summary.c: the lines of `read FILE`,
 * with the summary table of $MAVSCOPE_FUZZ_SUMMARY and a t0 picked by the input's length: none, the
 * capture's era, 0, or NaN); each line must end in one newline and hold printable ASCII and the route's
 * arrow only. The summary number and string writers (ms_w_f32_repr and ms_w_double_repr, the shortest
 * text of a float32 and Python's repr of a double, in MS_REPR_MAX; ms_w_degrees, ms_w_reltime,
 * ms_w_repr_ascii) run on the input's bytes into buffers of exactly their claimed room too. Every float
 * text (JSON's ms_w_double and ms_w_f32, the summary's repr layouts) must read back (strtod, strtof) as the
 * value written, and a float32's hold no more digits than the fewest printf's %.*e reads back with.
 *
 * Every walk is given the notes the walker writes itself and MAVLink's UDP ports, as the glue gives them
 * ($MAVSCOPE_FUZZ_NOTES, written by the script from mavscope.native.walk.note_templates): unsigned and
 * MAVLink 1 frames of a sender seen signing (the preset sender, bits 4-6) and frames with a bad CRC (bit 3
 * clear) are written natively with their notes, JSON and summary (" [CRC bad]") alike.
 *
 * Live capture's parts run on every input too: ms_udp_record (recv.c) on addresses, ports and a payload
 * taken from the input (lengths and checksums checked), and a pcap input is walked again fed in pieces
 * ending at record boundaries (ms_reader_extend), which must give the whole walk's output when its
 * record headers are sane.
 * Every input is then walked three times more into the export's column buffers (columns.c, in chunks of
 * 1 to 16 frames picked by the input's length, each checked and started over; the limit changed after
 * each take): the export's full walk without notes, the same with `notes` (as Columns(notes=True) has it:
 * frames whose only notes are "unsigned/v1 frame of a sender seen signing" and "bad CRC" taken, their
 * MS_NOTE_* bits in the note column) and the TUI's index-only walk. Every frame's wire bytes must be the
 * file's at the offset its column states, its header columns and payload those bytes', every fixed-width
 * column one value per frame, the offsets in order and inside their bytes, each message row its frame's
 * payload zero-extended to the message's length and pointing at a frame of that message, endpoint ids
 * known. The note column: one byte per frame, only MS_NOTE_UNSIGNED (an unsigned MAVLink 2 frame),
 * MS_NOTE_V1 (a MAVLink 1 frame) and MS_NOTE_BAD_CRC (an unsigned frame whose CRC the harness recomputes
 * as bad, every bad one so marked), all zero without `notes`; a bad-CRC frame has no message row, every
 * other frame exactly one. A raw stream (selector 3) is walked by walk_raw in the column walks too (clean
 * stretches into the columns, cut at their limit, pieces handed back, the framer's state made up after each
 * piece): each of its rows must be a record of its own (numbers rising within the chunk), index 1, without
 * time or endpoints, transport MS_TRANSPORT_RAW; every other capture's rows UDP (both endpoints) or tlog
 * (none).
 * Signed frames with keys (signing.c, sha256.c): with selector bit 2 clear and a preset sender (bits
 * 4-6), the walk judges signed frames against a signing state (MS_SIGNED_VERIFY) holding four keys
 * (the bench capture's, the bundled captures' "mavscope-demo", one whose name is as long as the writer
 * takes, one without a name) and streams preset for the usual senders; bit 3 takes every MAC for good
 * too. After each handed-back record the harness does what the Python verifier would: each signed frame
 * in it whose MAC one of the keys makes opens or advances its stream. SHA-256 is checked against
 * itself (one piece against many), the MAC check against the digest, and the `valid` signature object
 * and the skew's rounding run on the input's bytes into buffers of exactly their claimed room.
 *
 * Build and run: scripts/fuzz-native.sh SECONDS (docs/native.md). The message table comes from
 * mavscope's default dialect, written by the script to the file named in $MAVSCOPE_FUZZ_TABLE. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "columns.h"
#include "decode.h"
#include "fmt.h"
#include "mavlink.h"
#include "recv.h"
#include "sha256.h"
#include "signing.h"
#include "summary.h"
#include "table.h"
#include "walk.h"

static ms_table table;
static ms_summary summary;
/* the note templates (walk.h MS_TPL_*) and ports of $MAVSCOPE_FUZZ_NOTES, pointing into notes_blob */
static uint8_t notes_blob[4096];
static const char *tpl[MS_NOTE_TPLS][4];
static size_t tpl_len[MS_NOTE_TPLS][4];
static uint16_t tpl_ports[64];
static size_t tpl_nports;

/* notes.bin (scripts/fuzz_native_inputs.py notes_blob): per template u8 piece count, then per piece u16
 * length and bytes; u16 port count, u16 ports (little-endian). 0, or -1 when malformed. */
static int parse_notes(size_t n) {
    size_t p = 0;
    for (int i = 0; i < MS_NOTE_TPLS; i++) {
        if (p >= n || notes_blob[p] == 0 || notes_blob[p] > 4)
            return -1;
        const unsigned pieces = notes_blob[p++];
        for (unsigned j = 0; j < pieces; j++) {
            if (n - p < 2)
                return -1;
            const size_t len = (size_t)notes_blob[p] | (size_t)notes_blob[p + 1] << 8;
            p += 2;
            if (len > MS_NOTE_TPL_MAX || n - p < len)
                return -1;
            tpl[i][j] = (const char *)notes_blob + p;
            tpl_len[i][j] = len;
            p += len;
        }
    }
    if (n - p < 2)
        return -1;
    tpl_nports = (size_t)notes_blob[p] | (size_t)notes_blob[p + 1] << 8;
    p += 2;
    if (tpl_nports > sizeof tpl_ports / sizeof tpl_ports[0] || n - p != 2 * tpl_nports)
        return -1;
    for (size_t i = 0; i < tpl_nports; i++, p += 2)
        tpl_ports[i] = (uint16_t)(notes_blob[p] | notes_blob[p + 1] << 8);
    return 0;
}

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
    const char *npath = getenv("MAVSCOPE_FUZZ_NOTES");
    if (npath == NULL) {
        fprintf(stderr, "fuzz_native: set MAVSCOPE_FUZZ_NOTES to the note templates (scripts/fuzz-native.sh)\n");
        abort();
    }
    f = fopen(npath, "rb");
    if (f == NULL) {
        perror(npath);
        abort();
    }
    n = fread(notes_blob, 1, sizeof notes_blob, f);
    fclose(f);
    if (n == sizeof notes_blob || parse_notes(n) != 0) {
        fprintf(stderr, "fuzz_native: %s is not a notes blob\n", npath);
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

/* The significant digits of a number's text (its digits before any exponent, leading and trailing zeros
 * not counted). */
static int significant_digits(const char *s, const char *e) {
    int n = 0, zeros = 0, started = 0;
    for (; s < e && *s != 'e' && *s != 'E'; s++) {
        if (*s < '0' || *s > '9')
            continue;
        if (*s == '0') {
            zeros += started;
            continue;
        }
        n += started ? zeros + 1 : 1;
        zeros = 0;
        started = 1;
    }
    return n;
}

/* A float text [s, e) of the double d (f32: of the float32 f): JSON's `null` for NaN and infinities (json),
 * else a number (a JSON one with json) that strtod/strtof reads back as exactly the value (its sign too);
 * with `shortest`, a float32's or a double's text holds no more significant digits than the fewest that
 * printf's correctly rounded %.*e reads back with (the shortest may be fewer: a power of two's interval is
 * lopsided). */
static void check_float_text(const char *s, const char *e, int f32, double d, float f, int json, int shortest) {
    char buf[64];
    const size_t len = (size_t)(e - s);
    if (e <= s || len >= sizeof buf)
        abort();
    memcpy(buf, s, len);
    buf[len] = '\0';
    const double v = f32 ? (double)f : d;
    if (!isfinite(v)) {
        if (json && strcmp(buf, "null") != 0)
            abort();
        return;
    }
    const char *q = s;
    if (json && (!json_number(&q, e) || q != e))
        abort();
    char *stop;
    errno = 0;
    if (f32) {
        const float back = strtof(buf, &stop);
        if (*stop != '\0' || memcmp(&back, &f, sizeof f) != 0)
            abort(); /* the text does not read back as the float32 written */
    } else {
        const double back = strtod(buf, &stop);
        if (*stop != '\0' || memcmp(&back, &d, sizeof d) != 0)
            abort();
    }
    if (!shortest || v == 0)
        return;
    const int most = f32 ? 9 : 17;
    int fewest = most;
    for (int p = 1; p < most; p++) {
        char t[64];
        snprintf(t, sizeof t, "%.*e", p - 1, v);
        if (f32 ? strtof(t, NULL) == f : strtod(t, NULL) == d) {
            fewest = p;
            break;
        }
    }
    if (significant_digits(s, e) > fewest)
        abort(); /* not the shortest text that reads back */
}

/* ms_w_double on doubles and widened floats from the input, ms_w_f32 on its float32s (JSON Lines' float
 * fields), ms_w_text on a piece of it, each into a heap buffer of exactly the room it claims; each number
 * reads back as the value written, the first ones' texts the shortest. */
static void check_writers(const uint8_t *data, size_t size) {
    char *room = malloc(MS_DOUBLE_MAX);
    if (room == NULL)
        return;
    for (size_t i = 0; i + 8 <= size && i < 512; i += 8) {
        const int shortest = i < 64;
        uint64_t bits;
        memcpy(&bits, data + i, 8);
        double d;
        memcpy(&d, &bits, 8);
        char *end = ms_w_double(room, d);
        if (end <= room || end > room + 24)
            abort(); /* no double text is longer than 24 bytes */
        check_float_text(room, end, 0, d, 0, 1, shortest);
        float f;
        memcpy(&f, data + i, 4);
        end = ms_w_double(room, (double)f);
        if (end <= room || end > room + 24)
            abort();
        check_float_text(room, end, 0, (double)f, 0, 1, 0);
        for (int k = 0; k < 2; k++) {
            memcpy(&f, data + i + 4 * k, 4);
            end = ms_w_f32(room, f);
            if (end <= room || end > room + 19)
                abort(); /* "-1234567800000000.0": 9 digits at most, 16 before the point */
            check_float_text(room, end, 1, 0, f, 1, shortest);
        }
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


/* SHA-256 in one piece and in pieces cut where the input says, the MAC check against the digest, and
 * the writers of a judged signature (its skew rounded as Python's round(x, 6)) into exact rooms. */
static void check_signing(const uint8_t *data, size_t size) {
    uint8_t one[MS_SHA256_LEN], many[MS_SHA256_LEN];
    ms_sha256 h;
    ms_sha256_init(&h);
    ms_sha256_update(&h, data, size);
    ms_sha256_final(&h, one);
    ms_sha256_init(&h);
    size_t done = 0, cut = size ? data[0] : 0;
    while (done < size) {
        size_t take = size - done < cut + 1 ? size - done : cut + 1;
        ms_sha256_update(&h, data + done, take);
        done += take;
        cut = data[done - 1] % 97;
    }
    ms_sha256_final(&h, many);
    if (memcmp(one, many, MS_SHA256_LEN) != 0)
        abort();
    if (size >= 32 + 6) { /* a key of the input's first 32 bytes, a MAC over the rest */
        ms_signing s;
        ms_signing_init(&s);
        if (ms_signing_add_key(&s, data, "\"k\"", 3) == 0) {
            uint8_t digest[MS_SHA256_LEN];
            ms_sha256_init(&h);
            ms_sha256_update(&h, data, size - 6);
            ms_sha256_final(&h, digest);
            const int same = memcmp(digest, data + size - 6, 6) == 0;
            if (ms_signing_mac_ok(&s.keys[0], data + 32, size - 38, data + size - 6) != same ||
                !ms_signing_mac_ok(&s.keys[0], data + 32, size - 38, digest))
                abort();
        }
        ms_signing_free(&s);
    }
    char *room = malloc(MS_DOUBLE_MAX);
    char *sig = malloc(MS_SIGNATURE_JSON_MAX + MS_SIGNATURE_VALID_EXTRA);
    char name[MS_SIGN_NAME_MAX];
    memset(name, 'n', sizeof name);
    name[0] = name[sizeof name - 1] = '"';
    for (size_t i = 0; room != NULL && sig != NULL && i + 21 <= size && i < 512; i += 8) {
        double d;
        memcpy(&d, data + i, 8);
        const double r = ms_round6(d);
        if (!(r == r) != !(d == d) || (d == d && fabs(r - d) > 5e-7 + fabs(d) * 0x1p-51))
            abort(); /* round(x, 6) moves a value by half a millionth at most (and the read-back's rounding) */
        char *end = ms_w_double(room, r);
        if (end <= room || end > room + 24)
            abort();
        end = ms_w_signature_valid(sig, data + i + 8, name, sizeof name, (int)(data[i] & 1), d);
        const char *q = sig;
        if (!json_value(&q, end, 0) || q != end)
            abort();
    }
    free(room);
    free(sig);
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
    char *g = malloc(MS_REPR_MAX), *deg = malloc(MS_DEG_MAX), *rel = malloc(MS_REL_MAX);
    if (g == NULL || deg == NULL || rel == NULL)
        goto done;
    for (size_t i = 0; i + 8 <= size && i < 256; i += 8) {
        const int shortest = i < 64;
        uint64_t bits;
        memcpy(&bits, data + i, 8);
        double d;
        memcpy(&d, &bits, 8);
        float f;
        memcpy(&f, data + i, 4);
        /* the Info column's floats (summary.c w_float): finite values only, NaN and inf are its own words */
        if (isfinite(d)) {
            char *end = ms_w_double_repr(g, d);
            if (end <= g || end > g + 24)
                abort(); /* "-1.2345678901234567e-308" */
            check_float_text(g, end, 0, d, 0, 0, shortest);
        }
        for (int k = 0; k < 2; k++) {
            memcpy(&f, data + i + 4 * k, 4);
            if (!isfinite(f))
                continue;
            char *end = ms_w_f32_repr(g, f);
            if (end <= g || end > g + 19)
                abort();
            check_float_text(g, end, 1, 0, f, 0, shortest);
        }
        memcpy(&f, data + i, 4);
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

/* An index-only chunk (the TUI's index: columns.h MS_INDEX_COLUMNS) against the file it was read from. */
static void check_index_columns(const ms_cols *c, const uint8_t *file, size_t size) {
    const size_t n = c->n;
    for (int k = 0; k < MS_NCOLS; k++) {
        const size_t want = ((MS_INDEX_COLUMNS >> k) & 1u) ? n * MS_COL_WIDTH[k] : 0;
        if (c->col[k].len != want)
            abort(); /* the columns the index does not take stay empty */
    }
    if (c->ntouched != 0)
        abort(); /* no message rows */
    for (size_t i = 0; i < n; i++) {
        int64_t off;
        uint16_t len;
        uint32_t msgid;
        int32_t src, dst;
        memcpy(&off, c->col[MS_COL_OFFSET].data + 8 * i, 8);
        memcpy(&len, c->col[MS_COL_SIZE].data + 2 * i, 2);
        memcpy(&msgid, c->col[MS_COL_MSGID].data + 4 * i, 4);
        memcpy(&src, c->col[MS_COL_SRC].data + 4 * i, 4);
        memcpy(&dst, c->col[MS_COL_DST].data + 4 * i, 4);
        if (off < 0 || (uint64_t)off > size || len > size - (size_t)off || len < 8)
            abort(); /* the frame lies in the file */
        const uint8_t *raw = file + off;
        const int v2 = raw[0] == MS_STX_V2;
        if (!v2 && raw[0] != MS_STX_V1)
            abort();
        const uint32_t id = v2 ? (uint32_t)raw[7] | ((uint32_t)raw[8] << 8) | ((uint32_t)raw[9] << 16) : raw[5];
        const size_t hlen = v2 ? MS_HEADER_V2 : MS_HEADER_V1;
        if (hlen + raw[1] + 2u > len || id != msgid || ms_table_get(c->table, msgid) == NULL)
            abort();
        if ((uint8_t)c->col[MS_COL_SEQ].data[i] != raw[v2 ? 4 : 2] ||
            (uint8_t)c->col[MS_COL_SYSID].data[i] != raw[v2 ? 5 : 3] ||
            (uint8_t)c->col[MS_COL_COMPID].data[i] != raw[v2 ? 6 : 4] ||
            (uint8_t)c->col[MS_COL_IFLAGS].data[i] != (v2 ? raw[2] : 0))
            abort();
        if (src < -1 || dst < -1 || (src >= 0 && (uint32_t)src >= c->nends) || (dst >= 0 && (uint32_t)dst >= c->nends))
            abort();
    }
}

/* Every frame's record, index, time, transport and endpoints as the Python pipeline has them: a raw stream's
 * (`raw`) each a record of its own (numbered on, so strictly increasing within a chunk), index 1, no time,
 * transport raw, no endpoints (Dissector._stream); another capture's transport UDP or tlog, a tlog entry's
 * without endpoints, a datagram's with both. */
static void check_record_columns(const ms_cols *c, int raw) {
    int64_t last = 0;
    for (size_t i = 0; i < c->n; i++) {
        int64_t record;
        double time;
        memcpy(&record, c->col[MS_COL_RECORD].data + 8 * i, 8);
        memcpy(&time, c->col[MS_COL_TIME].data + 8 * i, 8);
        const int32_t index = i32_at(&c->col[MS_COL_INDEX], i), src = i32_at(&c->col[MS_COL_SRC], i),
                      dst = i32_at(&c->col[MS_COL_DST], i);
        const uint8_t transport = (uint8_t)c->col[MS_COL_TRANSPORT].data[i];
        const uint8_t time_ok = (uint8_t)c->col[MS_COL_TIME_OK].data[i];
        if (raw) {
            if (transport != MS_TRANSPORT_RAW || index != 1 || time_ok != 0 || time != 0.0 || src != -1 ||
                dst != -1 || record <= last)
                abort();
            last = record;
        } else if (index < 1 || (transport == MS_TRANSPORT_TLOG ? src != -1 || dst != -1
                                 : transport != MS_TRANSPORT_UDP || src < 0 || dst < 0)) {
            abort();
        }
    }
}

/* The endpoint cache in front of the map holds only what the map holds. */
static void check_endpoint_cache(const ms_cols *c) {
    for (int r = 0; r < 8; r++)
        if (c->recent_ok[r] && (c->recent_id[r] >= c->nends ||
                                memcmp(&c->ends[c->recent_id[r]], &c->recent[r], sizeof c->recent[r]) != 0))
            abort();
}

/* MAVLink's X.25 checksum (CRC-16/MCRF4XX) of the frame's bytes after STX and the message's CRC_EXTRA, as
 * mavlink_helpers.h crc_accumulate computes it (written here, not mavlink.c's ms_crc16: the harness judges
 * the note column's bad-CRC bit on its own). */
static uint16_t x25(const uint8_t *p, size_t n, uint8_t extra) {
    uint16_t crc = 0xFFFF;
    for (size_t i = 0; i <= n; i++) {
        uint8_t t = (uint8_t)((i < n ? p[i] : extra) ^ (crc & 0xFF));
        t = (uint8_t)(t ^ (t << 4));
        crc = (uint16_t)((crc >> 8) ^ ((uint16_t)t << 8) ^ ((uint16_t)t << 3) ^ (t >> 4));
    }
    return crc;
}

#define RADIO_STATUS_ID 109 /* unsigned in a signed stream without a note (security/stage.py) */

/* A chunk of the column buffers against the file they were read from; `any_crc`: the walk took every CRC
 * for good (fuzz_any_crc). */
static void check_columns(const ms_cols *c, const uint8_t *file, size_t size, int any_crc, int raw) {
    const size_t n = c->n;
    check_endpoint_cache(c);
    check_record_columns(c, raw);
    if (c->index_only) {
        check_index_columns(c, file, size);
        return;
    }
    uint8_t *seen = calloc(n ? n : 1, 1); /* message rows pointing at each frame */
    if (seen == NULL)
        abort();
    size_t bad = 0;
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
        uint16_t fsize;
        memcpy(&fsize, c->col[MS_COL_SIZE].data + 2 * i, 2);
        if (off < 0 || (uint64_t)off > size || len > size - (size_t)off || len < 8 || memcmp(raw, file + off, len) ||
            fsize != len)
            abort(); /* a frame's bytes are the file's where its offset says, its size theirs */
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
        const int32_t m = i32_at(&c->col[MS_COL_MESSAGE], i), src = i32_at(&c->col[MS_COL_SRC], i),
                      dst = i32_at(&c->col[MS_COL_DST], i);
        const uint32_t msgid = (uint32_t)i32_at(&c->col[MS_COL_MSGID], i);
        if (m < 0 || (size_t)m >= c->table->count || c->table->messages[m].msgid != msgid)
            abort();
        if (src < -1 || dst < -1 || (src >= 0 && (uint32_t)src >= c->nends) || (dst >= 0 && (uint32_t)dst >= c->nends))
            abort();
        /* the note column (columns.h MS_NOTE_*): zero without `notes`; with it an unsigned MAVLink 2 or a
         * MAVLink 1 frame's bit (never both, never RADIO_STATUS's), and the bad-CRC bit exactly when the
         * CRC as sent is not the frame's (unsigned frames only: the walk hands signed bad ones back) */
        const uint8_t note = (uint8_t)c->col[MS_COL_NOTE].data[i];
        const int is_signed = version == 2 && (raw[2] & 1);
        const int crc_bad = !any_crc && x25(raw + 1, hlen - 1 + plen, c->table->messages[m].crc_extra) !=
                                            (uint16_t)(raw[hlen + plen] | raw[hlen + plen + 1] << 8);
        if ((note & ~(MS_NOTE_UNSIGNED | MS_NOTE_V1 | MS_NOTE_BAD_CRC)) || (!c->notes && note) ||
            !(note & MS_NOTE_BAD_CRC) != !crc_bad)
            abort();
        if ((note & MS_NOTE_UNSIGNED) && (version != 2 || is_signed || (note & MS_NOTE_V1)))
            abort();
        if ((note & MS_NOTE_V1) && version != 1)
            abort();
        if ((note & (MS_NOTE_UNSIGNED | MS_NOTE_V1)) && msgid == RADIO_STATUS_ID)
            abort();
        if ((note & MS_NOTE_BAD_CRC) && is_signed)
            abort();
        bad += (note & MS_NOTE_BAD_CRC) != 0;
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
            if (f >= n || seen[f]++ || (c->col[MS_COL_NOTE].data[f] & MS_NOTE_BAD_CRC))
                abort(); /* one row per frame, none for a frame with a bad CRC (its fields are no one's) */
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
    free(seen);
    if (rows + bad != n)
        abort(); /* every frame but the bad-CRC ones in its message's rows */
}

/* The signing state of a walk that judges signed frames: four keys, streams preset for the usual senders
 * and the preset one, with last timestamps picked by the input's length. */
static int signing_setup(ms_signing *s, unsigned preset, size_t n) {
    static const char *const NAMES[3] = {"\"key1\"", "\"demo\"", NULL};
    static const uint8_t DEMO[32] = {0xac, 0x21, 0x93, 0xec, 0xb3, 0xbe, 0x4d, 0x7e, 0x44, 0x4e, 0x28,
                                     0x67, 0xd4, 0x30, 0xa8, 0xb1, 0x61, 0x8c, 0xd2, 0xac, 0x1e, 0xd9,
                                     0x71, 0x0d, 0x58, 0x0a, 0x79, 0x63, 0x0f, 0x54, 0x20, 0xf0};
    uint8_t secret[32];
    char longest[MS_SIGN_NAME_MAX];
    memset(longest, 'x', sizeof longest);
    longest[0] = longest[sizeof longest - 1] = '"';
    ms_signing_init(s);
    for (int k = 0; k < 4; k++) {
        for (int i = 0; i < 32; i++)
            secret[i] = k == 1 ? DEMO[i] : (uint8_t)(i + 64 * k); /* key 0: bytes(range(32)), the bench's */
        const char *name = k < 2 ? NAMES[k] : k == 2 ? longest : NULL;
        if (ms_signing_add_key(s, secret, name, k == 2 ? sizeof longest : name ? strlen(name) : 0) < 0)
            return -1;
    }
    static const unsigned SYSIDS[5] = {1, 2, 254, 255, 0};
    for (int i = 0; i < 5; i++) {
        const unsigned sysid = i == 4 ? preset : SYSIDS[i];
        for (unsigned c = 0; c < 2; c++)
            for (unsigned link = 0; link < 4; link++) /* 40 streams: past the first table size */
                if (ms_signing_put(s, ms_sign_stream(sysid, c ? 190 : 1, link), (n * 7919u * (link + 1)) % 1000003u,
                                   (sysid + link) % 4) != 0)
                    return -1;
    }
    return 0;
}

/* What the Python verifier does with a handed-back record, roughly: each whole signed MAVLink 2 frame in
 * it whose MAC a key makes opens its stream or moves it on. Bounded: a MAC per whole frame found. */
static void learn_streams(ms_signing *s, const uint8_t *d, size_t n) {
    size_t p = 0;
    while (p + 12 <= n) {
        const size_t size = 12 + (size_t)d[p + 1] + 13;
        if (d[p] != 0xFD || !(d[p + 2] & 1) || size > n - p) {
            p++;
            continue;
        }
        const uint8_t *f = d + p, *sig = f + size - 13;
        uint64_t ts = 0;
        for (int i = 6; i >= 1; i--)
            ts = (ts << 8) | sig[i];
        for (size_t k = 0; k < s->nkeys; k++) {
            if (!ms_signing_mac_ok(&s->keys[k], f, size - 6, sig + 7))
                continue;
            const uint32_t stream = ms_sign_stream(f[5], f[6], sig[0]);
            const ms_sign_entry *e = ms_signing_find(s, stream);
            if (e == NULL || ts > e->last)
                (void)ms_signing_put(s, stream, ts, (uint32_t)k);
            break;
        }
        p += size;
    }
}

/* The notes the walker writes itself and MAVLink's ports, as the glue gives them (module.c: the templates
 * copied, the ports an exactly sized list; $MAVSCOPE_FUZZ_NOTES): set on every walk, so the unsigned and
 * MAVLink 1 frames of a sender that signs and the bad-CRC frames are written natively as the glue has them
 * written. */
static void set_notes(ms_walker *w) {
    for (int i = 0; i < MS_NOTE_TPLS; i++)
        for (int j = 0; j < 4 && tpl[i][j] != NULL; j++) {
            char *piece = malloc(tpl_len[i][j] + 1); /* the walker frees them, as the glue's copies */
            if (piece == NULL)
                abort();
            memcpy(piece, tpl[i][j], tpl_len[i][j]);
            piece[tpl_len[i][j]] = '\0';
            w->note_tpl[i][j] = piece;
            w->note_tpl_len[i][j] = tpl_len[i][j];
        }
    uint16_t *ports = malloc(tpl_nports ? tpl_nports * sizeof *ports : 1); /* exactly sized: a read past is an overflow */
    if (ports == NULL)
        abort();
    memcpy(ports, tpl_ports, tpl_nports * sizeof *ports);
    w->ports = ports;
    w->nports = tpl_nports;
}

/* One walk of the file in `mf` (as JSON Lines, or as summary lines with `sum`), checking what comes out. */
static void walk_file(ms_memory_file *mf, const uint8_t *file, size_t n, unsigned sel, unsigned control,
                      const ms_summary *sum, ms_cols *cols) {
    ms_walker w;
    ms_walker_init(&w, ms_memory_source(mf), n, MS_KIND_PCAP + (int)(sel & 3), &table);
    if (sel & 0x80)
        w.reader.window = (size_t)64 << (control & 7);
    const unsigned preset = (sel >> 4) & 7;
    ms_signing signing;
    ms_signing_init(&signing);
    w.sign_mode = (sel & 4) ? MS_SIGNED_NOKEY : preset ? MS_SIGNED_VERIFY : MS_SIGNED_HANDBACK;
    if (w.sign_mode == MS_SIGNED_VERIFY && cols != NULL)
        w.sign_mode = MS_SIGNED_HANDBACK; /* the column walks never judge MACs (their glue hands back) */
    if (w.sign_mode == MS_SIGNED_VERIFY) {
        if (signing_setup(&signing, preset, n) != 0) {
            ms_signing_free(&signing);
            ms_walker_free(&w);
            return;
        }
        w.signing = &signing;
    }
    w.fuzz_any_crc = (sel & 8) != 0;
    w.fuzz_any_mac = (sel & 8) != 0;
    set_notes(&w);
    if (sum != NULL) {
        static const double T0[4] = {0.0, 1.7e9, 0.0, 0.0};
        w.summary = sum;
        w.has_t0 = (n & 3) != 0;
        w.t0 = (n & 3) == 3 ? __builtin_nan("") : T0[n & 3];
    }
    w.cols = cols;
    /* a raw stream in every walk: clean stretches written (or put into the columns, as far as their limit), pieces
     * handed back (walk.c walk_raw); after each piece the framer's state is made up below, as any RawLink may
     * report it */
    w.raw_native = (sel & 3) == 3;
    unsigned steps = 0;
    ms_buf out;
    ms_buf_init(&out);
    /* the sources Python's Dissector.mavlink_endpoints takes (module.c sync_endpoints): without room for
     * them every datagram of a new source is handed back */
    const size_t endpoints_max = (sel & 0x80) && (control & 0x40) ? 1 + n % 3 : MS_MAX_ENDPOINTS;
    size_t endpoints = 0;
    for (;;) {
        if (preset)
            ms_signer_set(&w, (preset << 8) | 1u); /* a sender seen signing, as Python may add */
        w.endpoint_room = endpoints >= endpoints_max ? 0 : endpoints_max - endpoints;
        out.len = 0;
        ms_record rec;
        int r = ms_walk(&w, &out, 4096, &rec);
        if (r == MS_WALK_NOMEM)
            break;
        if (cols != NULL) {
            if (out.len != 0)
                abort(); /* column mode writes no text */
            if (r != MS_WALK_FULL || ms_cols_full(cols)) {
                check_columns(cols, file, n, (sel & 8) != 0, w.raw_native);
                ms_cols_restart(cols);
                cols->limit = 1 + ((cols->limit * 5 + 3) & 31); /* the glue may change it between chunks */
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
            if (w.signing != NULL && rec.len)
                learn_streams(&signing, rec.data, rec.len);
            if (w.raw_native) { /* idle, or holding some of the last bytes (or more than it was fed) */
                steps++;
                w.raw_held = (steps * 7 + control) % 3 == 0 ? -1 : (int64_t)((steps * 131u + rec.len) % 700u);
                w.raw_frames += steps & 3;
            }
        }
        if (r == MS_WALK_END)
            break;
        endpoints += w.n_new_endpoints;
        w.n_new_signers = 0;
        w.n_new_endpoints = 0;
    }
    ms_buf_free(&out);
    ms_walker_free(&w);
    ms_signing_free(&signing);
}

/* ---- live capture: records made of datagrams, and a pcap that grows (recv.c, ms_reader_extend) ---- */

static unsigned fold_sum(const uint8_t *p, size_t n, uint64_t acc) {
    for (size_t i = 0; i + 1 < n; i += 2)
        acc += ((uint64_t)p[i] << 8) | p[i + 1];
    if (n & 1)
        acc += (uint64_t)p[n - 1] << 8;
    while (acc >> 16)
        acc = (acc & 0xFFFF) + (acc >> 16);
    return (unsigned)acc;
}

/* ms_udp_record on addresses, ports, a time and a payload taken from the input: the record must have
 * the lengths it claims and checksums a receiver verifies (the one's-complement sums come to 0xFFFF). */
static void check_udp_record(const uint8_t *d, size_t n) {
    if (n < 40)
        return;
    ms_addr src = {(uint8_t)((d[0] & 1) ? 16 : 4), {0}}, dst = {(uint8_t)((d[0] & 2) ? 16 : 4), {0}};
    memcpy(src.addr, d + 1, 16);
    memcpy(dst.addr, d + 17, 16);
    const uint16_t sport = (uint16_t)(d[33] << 8 | d[34]), dport = (uint16_t)(d[35] << 8 | d[36]);
    const size_t plen = n - 37;
    uint8_t *payload = malloc(plen ? plen : 1); /* exactly sized: a read past it is a heap overflow */
    if (payload == NULL)
        return;
    memcpy(payload, d + 37, plen);
    ms_buf out;
    ms_buf_init(&out);
    int rc = ms_udp_record(&out, d[0], (uint32_t)d[1] * 3906250u, &src, sport, &dst, dport, payload, plen);
    if (rc == 0) {
        const uint8_t *r = (const uint8_t *)out.data;
        const int v4 = src.len == 4 && dst.len == 4;
        const size_t head = 14 + (v4 ? 20 : 40) + 8;
        const uint32_t incl = (uint32_t)r[8] | (uint32_t)r[9] << 8 | (uint32_t)r[10] << 16 | (uint32_t)r[11] << 24;
        if (out.len != 16 + head + plen || incl != head + plen || memcmp(r + 16 + head, payload, plen) != 0)
            abort();
        const uint8_t *ip = r + 16 + 14, *udp = ip + (v4 ? 20 : 40);
        uint64_t pseudo = 8 + plen + 17;
        if (v4) {
            if (fold_sum(ip, 20, 0) != 0xFFFF)
                abort();
            pseudo += fold_sum(ip + 12, 8, 0);
        } else {
            pseudo += fold_sum(ip + 8, 32, 0);
        }
        if (fold_sum(udp, 8 + plen, pseudo) != 0xFFFF)
            abort();
        /* the microsecond copy of the record: the same record but for its time; cut short, refused */
        uint8_t *rec = malloc(out.len);
        if (rec != NULL) {
            memcpy(rec, out.data, out.len);
            ms_buf micro;
            ms_buf_init(&micro);
            if (ms_records_to_micro(rec, out.len, &micro) == 1 &&
                (micro.len != out.len || memcmp(micro.data + 8, rec + 8, out.len - 8) != 0 ||
                 (uint8_t)micro.data[4] + ((uint8_t)micro.data[5] << 8) + ((uint8_t)micro.data[6] << 16) +
                         ((uint32_t)(uint8_t)micro.data[7] << 24) > 999999u))
                abort();
            micro.len = 0;
            if (ms_records_to_micro(rec, out.len - 1 - (size_t)(d[2] % 16), &micro) != -1 && !micro.failed)
                abort();
            ms_buf_free(&micro);
            free(rec);
        }
    }
    ms_buf_free(&out);
    free(payload);
}

/* Walk to the end, appending the text and, for each handed-back record, its number to `all`. */
static int walk_collect(ms_walker *w, ms_buf *all) {
    ms_buf out;
    ms_buf_init(&out);
    int r;
    do {
        out.len = 0;
        ms_record rec;
        r = ms_walk(w, &out, 4096, &rec);
        ms_buf_put(all, out.data ? out.data : "", out.len);
        if (r == MS_WALK_HANDBACK) {
            char mark[32];
            int k = snprintf(mark, sizeof mark, "<record %llu>\n", (unsigned long long)rec.number);
            ms_buf_put(all, mark, (size_t)k);
        }
    } while (r == MS_WALK_FULL || r == MS_WALK_HANDBACK);
    ms_buf_free(&out);
    return r;
}

/* A pcap fed in pieces that end at record boundaries (chosen by `control`), as live capture feeds the
 * walker, must give what the whole file gives when every record header is sane (no resynchronisation,
 * whose scans see only the bytes fed so far); otherwise it must merely be safe. */
static void walk_fed(const uint8_t *file, size_t n, unsigned sel, unsigned control) {
    size_t bounds[64];
    size_t nb = 0;
    int sane = n >= 24;
    size_t pos = sane ? 24 : n;
    while (sane && pos + 16 <= n) {
        const uint8_t *h = file + pos;
        uint32_t incl = (uint32_t)h[8] | (uint32_t)h[9] << 8 | (uint32_t)h[10] << 16 | (uint32_t)h[11] << 24;
        uint32_t orig = (uint32_t)h[12] | (uint32_t)h[13] << 8 | (uint32_t)h[14] << 16 | (uint32_t)h[15] << 24;
        if (incl > 262144u || orig != incl || pos + 16 + incl > n) {
            sane = 0;
            break;
        }
        pos += 16 + incl;
        if (nb < 64 && ((control >> (nb & 7)) & 1))
            bounds[nb++] = pos;
    }
    if (pos != n)
        sane = 0;
    if (nb == 0 || bounds[nb - 1] != pos) {
        if (nb == 64)
            nb--;
        bounds[nb++] = pos; /* the last piece ends where the sane records end */
    }
    ms_buf whole, fed;
    ms_buf_init(&whole);
    ms_buf_init(&fed);
    ms_memory_file mf = {file, n, 0, 0, 0, 0};
    ms_walker w;
    ms_walker_init(&w, ms_memory_source(&mf), n, MS_KIND_PCAP, &table);
    w.sign_mode = (sel & 4) ? MS_SIGNED_NOKEY : MS_SIGNED_HANDBACK;
    w.fuzz_any_crc = (sel & 8) != 0;
    set_notes(&w);
    w.endpoint_room = MS_MAX_ENDPOINTS; /* (a 64 KiB input has fewer sources) */
    if ((sel >> 4) & 7)
        ms_signer_set(&w, ((sel >> 4) & 7) << 8 | 1u);
    walk_collect(&w, &whole);
    ms_walker_free(&w);
    ms_memory_file mf2 = {file, bounds[0], 0, 0, 0, 0};
    ms_walker_init(&w, ms_memory_source(&mf2), bounds[0], MS_KIND_PCAP, &table);
    w.sign_mode = (sel & 4) ? MS_SIGNED_NOKEY : MS_SIGNED_HANDBACK;
    w.fuzz_any_crc = (sel & 8) != 0;
    set_notes(&w);
    w.endpoint_room = MS_MAX_ENDPOINTS; /* (a 64 KiB input has fewer sources) */
    if ((sel >> 4) & 7)
        ms_signer_set(&w, ((sel >> 4) & 7) << 8 | 1u);
    int ok = walk_collect(&w, &fed) == MS_WALK_END;
    for (size_t i = 1; ok && i < nb; i++) {
        mf2.size = bounds[i];
        if (ms_reader_extend(&w.reader, bounds[i]) != 0) {
            if (sane)
                abort(); /* a clean end at a record boundary must let the pcap grow */
            ok = 0;
            break;
        }
        ok = walk_collect(&w, &fed) == MS_WALK_END;
    }
    ms_walker_free(&w);
    if (sane && ok && !whole.failed && !fed.failed &&
        (whole.len != fed.len || (whole.len && memcmp(whole.data, fed.data, whole.len) != 0)))
        abort();
    ms_buf_free(&whole);
    ms_buf_free(&fed);
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
    check_udp_record(data + head, size - head);
    check_signing(data + head, size - head);
    /* an exactly sized copy: a read past the end of the file is a heap overflow for ASan */
    size_t n = size - head;
    uint8_t *file = malloc(n ? n : 1);
    if (file == NULL)
        return 0;
    memcpy(file, data + head, n);
    for (int pass = 0; pass < 5; pass++) {
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
        cols.notes = pass == 3;      /* the export's windows: Columns(notes=True) */
        cols.index_only = pass == 4; /* the TUI's index: only the columns it takes */
        walk_file(&mf, file, n, sel, control, NULL, &cols);
        ms_cols_free(&cols);
    }
    if ((sel & 3) == 0) /* a pcap: fed in pieces as live capture feeds it */
        walk_fed(file, n, sel, control);
    free(file);
    return 0;
}
