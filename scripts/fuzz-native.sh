#!/usr/bin/env bash
# Fuzz the native core under AddressSanitizer + UndefinedBehaviorSanitizer with libFuzzer.
#
#   scripts/fuzz-native.sh [SECONDS] [JOBS]     (default 600 s, 1 job; docs/native.md)
#
# Needs clang with libFuzzer (Debian: apt-get install -y clang-14 libclang-rt-14-dev) and the project's
# .venv (for the message table, compiled from the default dialect). Builds fuzz/build/fuzz_native,
# seeds fuzz/build/corpus from captures/ (one copy per format selector), then runs. A finding leaves a
# crash-* file in fuzz/build/ and makes this script exit non-zero. Afterwards the corpus is replayed
# through a coverage build (llvm-profdata/llvm-cov, when installed) and the line coverage of the native
# sources printed; the fuzzer's own log is fuzz/build/fuzz-0.log.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_TO_RUN="${1:-600}"
JOBS="${2:-1}"
CLANG="${CLANG:-$(command -v clang-14 || command -v clang || true)}"
[ -n "$CLANG" ] || { echo "fuzz-native: clang not found (apt-get install -y clang-14 libclang-rt-14-dev)" >&2; exit 2; }
PY="${PYTHON:-.venv/bin/python}"
OUT=fuzz/build
mkdir -p "$OUT/corpus"

"$PY" - "$OUT/table.bin" "$OUT/summary.bin" "$OUT/plan.bin" <<'PYEOF'
import sys
from mavscope.mavlink.dialect import load_dialect
from mavscope.native import build_table
from mavscope.native_plan import build_plan
from mavscope.native_summary import build_summary_table
dialect = load_dialect()
open(sys.argv[1], "wb").write(build_table(dialect))
open(sys.argv[2], "wb").write(build_summary_table(dialect))
open(sys.argv[3], "wb").write(build_plan(dialect))
PYEOF

SRC=src/mavscope_native
"$CLANG" -std=c11 -g -O1 -Wall -Wextra -fno-omit-frame-pointer \
    -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
    -I"$SRC" fuzz/fuzz_native.c \
    "$SRC"/walk.c "$SRC"/capture.c "$SRC"/capture_pcap.c "$SRC"/capture_pcapng.c "$SRC"/capture_tlog.c \
    "$SRC"/netlayers.c "$SRC"/mavlink.c "$SRC"/table.c "$SRC"/decode.c "$SRC"/fmt.c "$SRC"/buf.c "$SRC"/summary.c \
    "$SRC"/plan.c "$SRC"/acc.c "$SRC"/acc_dump.c "$SRC"/seq.c "$SRC"/expert.c "$SRC"/control.c "$SRC"/gnss.c \
    "$SRC"/recv.c "$SRC"/columns.c "$SRC"/sha256.c "$SRC"/signing.c -ffp-contract=off -lm -o "$OUT/fuzz_native"

# Seeds: every bundled capture under the selector of its own format (0 pcap, 1 pcapng, 2 tlog, 3 raw),
# with and without native signed frames (bit 2), with every CRC taken (bit 3), judged with keys (a
# preset sender, bits 4-6, bit 2 clear), and as hostile files (bit 7: small read windows, shrinking, a
# failed read); and 600 frames of the bench capture (benchmarks/bench_capture.py, two senders signing).
# libFuzzer's -max_len bounds the size.
"$PY" - "$OUT/corpus" <<'PYEOF'
import hashlib, pathlib, sys, tempfile
sys.path.insert(0, "benchmarks")
from bench_capture import generate
from mavscope.capture.detect import detect_kind
corpus = pathlib.Path(sys.argv[1])
sel = {"pcap": 0, "pcapng": 1, "tlog": 2, "raw": 3}
bench = pathlib.Path(tempfile.mkdtemp()) / "bench.pcap"
generate(bench, 600)
for path in sorted(pathlib.Path("captures").glob("*")) + [bench]:
    if path.suffix in (".md", ".json"):
        continue
    data = path.read_bytes()
    base = sel[detect_kind(path)]
    for extra in (0, 4, 8, 12, 0x10, 0x18, 0x70):
        for piece in (data[:4096], data[:65536]):
            blob = bytes([base | extra]) + piece
            (corpus / hashlib.sha1(blob).hexdigest()).write_bytes(blob)
    # hostile files (bit 7): a 64-byte read window; a file that shrinks after 2 reads to 2/7; a failed read
    for control in (0x00, 0x10, 0x38):
        blob = bytes([base | 0x80, control]) + data[:16384]
        (corpus / hashlib.sha1(blob).hexdigest()).write_bytes(blob)
PYEOF

export MAVSCOPE_FUZZ_TABLE="$PWD/$OUT/table.bin"
export MAVSCOPE_FUZZ_SUMMARY="$PWD/$OUT/summary.bin"
export MAVSCOPE_FUZZ_PLAN="$PWD/$OUT/plan.bin"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
status=0
(cd "$OUT" && ./fuzz_native -max_total_time="$SECONDS_TO_RUN" -max_len=65536 -timeout=10 -rss_limit_mb=2048 \
    -jobs="$JOBS" -workers="$JOBS" -print_final_stats=1 corpus) || status=$?
grep -h -E "^#[0-9]+.*DONE|^Done|stat::" "$OUT"/fuzz-*.log 2>/dev/null | tail -n 8 || true
if ls "$OUT"/crash-* "$OUT"/leak-* "$OUT"/timeout-* "$OUT"/oom-* >/dev/null 2>&1; then
    echo "fuzz-native: findings in $OUT:" >&2
    ls "$OUT"/crash-* "$OUT"/leak-* "$OUT"/timeout-* "$OUT"/oom-* 2>/dev/null >&2
    status=1
fi

# Line coverage of the corpus (a second build, no sanitizers, with clang's source-based coverage)
PROFDATA="$(command -v llvm-profdata-14 || command -v llvm-profdata || true)"
LLVMCOV="$(command -v llvm-cov-14 || command -v llvm-cov || true)"
if [ -n "$PROFDATA" ] && [ -n "$LLVMCOV" ]; then
    "$CLANG" -std=c11 -O1 -fsanitize=fuzzer -fprofile-instr-generate -fcoverage-mapping -I"$SRC" \
        fuzz/fuzz_native.c "$SRC"/walk.c "$SRC"/capture.c "$SRC"/capture_pcap.c "$SRC"/capture_pcapng.c \
        "$SRC"/capture_tlog.c "$SRC"/netlayers.c "$SRC"/mavlink.c "$SRC"/table.c "$SRC"/decode.c "$SRC"/fmt.c \
        "$SRC"/buf.c "$SRC"/summary.c "$SRC"/plan.c "$SRC"/acc.c "$SRC"/acc_dump.c "$SRC"/seq.c "$SRC"/expert.c \
        "$SRC"/control.c "$SRC"/gnss.c "$SRC"/recv.c "$SRC"/columns.c "$SRC"/sha256.c "$SRC"/signing.c \
        -lm -o "$OUT/fuzz_native_cov"
    rm -f "$OUT"/cov.profraw
    (cd "$OUT" && LLVM_PROFILE_FILE=cov.profraw ./fuzz_native_cov -runs=0 corpus >/dev/null 2>&1) || true
    "$PROFDATA" merge -sparse "$OUT/cov.profraw" -o "$OUT/cov.profdata"
    "$LLVMCOV" report "$OUT/fuzz_native_cov" -instr-profile="$OUT/cov.profdata" "$SRC"/*.c
fi
exit $status
