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
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "decode.h"
#include "fmt.h"
#include "sha256.h"
#include "signing.h"
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

/* One walk of the file in `mf` (as JSON Lines, or as summary lines with `sum`), checking what comes out. */
static void walk_file(ms_memory_file *mf, const uint8_t *file, size_t n, unsigned sel, unsigned control,
                      const ms_summary *sum) {
    ms_walker w;
    ms_walker_init(&w, ms_memory_source(mf), n, MS_KIND_PCAP + (int)(sel & 3), &table);
    if (sel & 0x80)
        w.reader.window = (size_t)64 << (control & 7);
    const unsigned preset = (sel >> 4) & 7;
    ms_signing signing;
    ms_signing_init(&signing);
    w.sign_mode = (sel & 4) ? MS_SIGNED_NOKEY : preset ? MS_SIGNED_VERIFY : MS_SIGNED_HANDBACK;
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
    if (sum != NULL) {
        static const double T0[4] = {0.0, 1.7e9, 0.0, 0.0};
        w.summary = sum;
        w.has_t0 = (n & 3) != 0;
        w.t0 = (n & 3) == 3 ? __builtin_nan("") : T0[n & 3];
    }
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
        if (sum != NULL)
            check_summary_lines(out.data, out.len);
        else
            check_lines(out.data, out.len);
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
        }
        if (r == MS_WALK_END)
            break;
        w.n_new_signers = 0;
        w.n_new_endpoints = 0;
    }
    ms_buf_free(&out);
    ms_walker_free(&w);
    ms_signing_free(&signing);
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
    check_signing(data + head, size - head);
    /* an exactly sized copy: a read past the end of the file is a heap overflow for ASan */
    size_t n = size - head;
    uint8_t *file = malloc(n ? n : 1);
    if (file == NULL)
        return 0;
    memcpy(file, data + head, n);
    for (int pass = 0; pass < 2; pass++) {
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
        walk_file(&mf, file, n, sel, control, pass ? &summary : NULL);
    }
    free(file);
    return 0;
}
