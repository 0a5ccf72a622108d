#!/usr/bin/env bash
# Fuzz the native core under AddressSanitizer + UndefinedBehaviorSanitizer with libFuzzer.
#
#   scripts/fuzz-native.sh [SECONDS] [JOBS]     (default 600 s, 1 job; docs/native.md)
#
# Needs clang with libFuzzer (Debian: apt-get install -y clang-14 libclang-rt-14-dev) and the project's
# .venv (for the message table, compiled from the default dialect, and the walker's note templates).
# Builds fuzz/build/fuzz_native, seeds fuzz/build/corpus from captures/ (one copy per format selector),
# then runs. A finding leaves a crash-* file in fuzz/build/ and makes this script exit non-zero.
# Afterwards the corpus is replayed through a coverage build (llvm-profdata/llvm-cov, when installed) and
# the line coverage of the native sources printed; the fuzzer's own log is fuzz/build/fuzz-0.log.
# FUZZ_CFLAGS: more clang flags for the sanitizer build, e.g. -fsanitize-ignorelist=FILE to step over a
# finding already reported and not yet fixed (so that the run goes on past it); unset for a real run.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_TO_RUN="${1:-600}"
JOBS="${2:-1}"
CLANG="${CLANG:-$(command -v clang-14 || command -v clang || true)}"
[ -n "$CLANG" ] || { echo "fuzz-native: clang not found (apt-get install -y clang-14 libclang-rt-14-dev)" >&2; exit 2; }
PY="${PYTHON:-.venv/bin/python}"
OUT=fuzz/build
mkdir -p "$OUT/corpus"

# the default dialect's tables and the seed corpus (scripts/fuzz_native_inputs.py says what the seeds are)
"$PY" scripts/fuzz_native_inputs.py "$OUT" "$OUT/corpus"

SRC=src/mavscope_native
# the C core: every source but the CPython module's glue (module*.c)
CORE=()
for f in "$SRC"/*.c; do
    case "$(basename "$f")" in module*) ;; *) CORE+=("$f") ;; esac
done
"$CLANG" -std=c11 -g -O1 -Wall -Wextra -fno-omit-frame-pointer \
    -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
    ${FUZZ_CFLAGS:-} -I"$SRC" fuzz/fuzz_native.c "${CORE[@]}" -ffp-contract=off -lm -o "$OUT/fuzz_native"

export MAVSCOPE_FUZZ_TABLE="$PWD/$OUT/table.bin"
export MAVSCOPE_FUZZ_SUMMARY="$PWD/$OUT/summary.bin"
export MAVSCOPE_FUZZ_NOTES="$PWD/$OUT/notes.bin"
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
    "$CLANG" -std=c11 -O1 -fsanitize=fuzzer -fprofile-instr-generate -fcoverage-mapping ${FUZZ_CFLAGS:-} \
        -Wno-unused-command-line-argument -I"$SRC" fuzz/fuzz_native.c "${CORE[@]}" -ffp-contract=off -lm \
        -o "$OUT/fuzz_native_cov"
    rm -f "$OUT"/cov.profraw
    # (an input that aborts ends the replay before the profile is written: no report then, not a false one)
    if (cd "$OUT" && LLVM_PROFILE_FILE=cov.profraw ./fuzz_native_cov -runs=0 corpus >/dev/null 2>&1) &&
        [ -s "$OUT/cov.profraw" ]; then
        "$PROFDATA" merge -sparse "$OUT/cov.profraw" -o "$OUT/cov.profdata"
        "$LLVMCOV" report "$OUT/fuzz_native_cov" -instr-profile="$OUT/cov.profdata" "$SRC"/*.c
    else
        echo "fuzz-native: the coverage replay stopped on an input of the corpus (a finding?): no coverage report" >&2
        status=1
    fi
fi
exit $status
