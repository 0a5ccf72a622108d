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
 * Build and run: scripts/fuzz-native.sh SECONDS (docs/native.md). The message table comes from
 * mavscope's default dialect, written by the script to the file named in $MAVSCOPE_FUZZ_TABLE. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "capture.h"
#include "fmt.h"
#include "table.h"
#include "walk.h"

static ms_table table;

int LLVMFuzzerInitialize(int *argc, char ***argv);
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
    /* an exactly sized copy: a read past the end of the file is a heap overflow for ASan */
    size_t n = size - head;
    uint8_t *file = malloc(n ? n : 1);
    if (file == NULL)
        return 0;
    memcpy(file, data + head, n);
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
    ms_walker w;
    ms_walker_init(&w, ms_memory_source(&mf), n, MS_KIND_PCAP + (int)(sel & 3), &table);
    if (sel & 0x80)
        w.reader.window = (size_t)64 << (control & 7);
    w.sign_mode = (sel & 4) ? MS_SIGNED_NOKEY : MS_SIGNED_HANDBACK;
    w.fuzz_any_crc = (sel & 8) != 0;
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
        check_lines(out.data, out.len);
        if (r == MS_WALK_HANDBACK) {
            /* what the glue reads of a handed-back record: its bytes are the file's at its offset */
            if (rec.len && (rec.offset > n || rec.len > n - rec.offset || memcmp(rec.data, file + rec.offset, rec.len)))
                abort();
            volatile unsigned sum = 0;
            for (size_t i = 0; i < rec.notes->n; i++) {
                const ms_note *note = &rec.notes->v[i];
                if (note->msg_off + note->msg_len > rec.notes->text.len)
                    abort();
                for (size_t k = 0; k < note->msg_len; k++)
                    sum += (unsigned char)rec.notes->text.data[note->msg_off + k];
            }
            double t;
            (void)ms_record_time(&rec, &t);
            (void)sum;
        }
        if (r == MS_WALK_END)
            break;
        w.n_new_signers = 0;
        w.n_new_endpoints = 0;
    }
    ms_buf_free(&out);
    ms_walker_free(&w);
    free(file);
    return 0;
}
