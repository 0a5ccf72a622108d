/* The native walk alone, without Python: records -> JSON Lines (or summary lines) into memory, best of
 * N, CPU time.
 *
 *   S=src/mavscope_native
 *   gcc -std=c11 -O2 -I$S benchmarks/native_walk.c $S/walk.c $S/capture.c $S/capture_pcap.c \
 *       $S/capture_pcapng.c $S/capture_tlog.c $S/netlayers.c $S/mavlink.c $S/table.c $S/decode.c \
 *       $S/fmt.c $S/buf.c $S/summary.c -lm -o benchmarks/out/native_walk
 *   benchmarks/out/native_walk TABLE.bin CAPTURE KIND [REPEAT [SUMMARY.bin]]
 *
 * TABLE.bin: the layout table (scripts/fuzz-native.sh writes fuzz/build/table.bin); KIND: 1 pcap,
 * 2 pcapng, 3 tlog. Signed frames are written natively (no key), as `read -T jsonl` does without keys.
 * With SUMMARY.bin (fuzz/build/summary.bin) the summary lines of `read FILE`, times relative to the
 * first record's (taken from the walk's first record).
 * docs/performance.md ("Native engine") quotes it. */
#define _GNU_SOURCE
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "walk.h"

static double cpu_seconds(void) {
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: %s TABLE.bin CAPTURE KIND [REPEAT [SUMMARY.bin]]\n", argv[0]);
        return 2;
    }
    static uint8_t blob[1 << 20];
    FILE *f = fopen(argv[1], "rb");
    if (f == NULL) {
        perror(argv[1]);
        return 2;
    }
    size_t n = fread(blob, 1, sizeof blob, f);
    fclose(f);
    ms_table table;
    if (ms_table_parse(&table, blob, n) != 0) {
        fprintf(stderr, "%s: not a table blob\n", argv[1]);
        return 2;
    }
    static uint8_t sblob[1 << 20];
    ms_summary summary;
    int with_summary = argc > 5;
    if (with_summary) {
        f = fopen(argv[5], "rb");
        if (f == NULL) {
            perror(argv[5]);
            return 2;
        }
        n = fread(sblob, 1, sizeof sblob, f);
        fclose(f);
        if (ms_summary_parse(&summary, &table, sblob, n) != 0) {
            fprintf(stderr, "%s: not a summary blob of this table\n", argv[5]);
            return 2;
        }
    }
    int fd = open(argv[2], O_RDONLY);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0 || st.st_size == 0) {
        perror(argv[2]);
        return 2;
    }
    int kind = atoi(argv[3]);
    int repeat = argc > 4 ? atoi(argv[4]) : 5;
    double best = 1e30;
    unsigned long long frames = 0, bytes = 0, handed = 0;
    ms_buf out;
    ms_buf_init(&out);
    for (int r = 0; r < repeat; r++) {
        ms_walker w;
        ms_walker_init(&w, ms_fd_source(&fd), (uint64_t)st.st_size, kind, &table); /* pread, 1 MiB windows */
        w.sign_mode = MS_SIGNED_NOKEY;
        if (with_summary) {
            ms_walker first;
            ms_record rec;
            ms_walker_init(&first, ms_fd_source(&fd), (uint64_t)st.st_size, kind, &table);
            w.has_t0 = ms_reader_next(&first.reader, &rec) > 0 && ms_record_time(&rec, &w.t0) > 0;
            ms_walker_free(&first);
            w.summary = &summary;
        }
        double t0 = cpu_seconds();
        bytes = 0;
        for (;;) {
            out.len = 0;
            ms_record rec;
            int res = ms_walk(&w, &out, 1 << 20, &rec);
            bytes += out.len;
            if (res == MS_WALK_END || res == MS_WALK_NOMEM)
                break;
            w.n_new_signers = 0;
            w.n_new_endpoints = 0;
        }
        double dt = cpu_seconds() - t0;
        if (dt < best)
            best = dt;
        frames = w.frames_native;
        handed = w.records_handed_back;
        ms_walker_free(&w);
    }
    printf("best of %d: %.3f s CPU, %llu frames written (%llu records handed back), %.1f ns a frame, "
           "%llu bytes of text\n", repeat, best, frames, handed, best * 1e9 / (double)(frames ? frames : 1), bytes);
    ms_buf_free(&out);
    if (with_summary)
        ms_summary_free(&summary);
    ms_table_free(&table);
    close(fd);
    return 0;
}
