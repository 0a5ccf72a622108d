#!/usr/bin/env python3
"""Whole-process `mavscope stats` (text and `--json`): the native engine's time and peak memory.

    benchmarks/native_stats.py [--repeat N] [--out DIR] [--big-out DIR] [--skip-pure] [--skip-10m]
                               [--tlog-copies N]

Captures (generated once and cached, git-ignored):
- in DIR (default benchmarks/out/): the 1M-frame bench capture of bench_read.py (Ethernet/IPv4/UDP, 25%
  signed frames from two senders) and ardusub_log_tools_small.tlog x28 (about 1M frames), as
  native_jsonl.py makes them;
- in --big-out (default DIR): the same at 10M frames: the bench pcap's records ten times over (one pcap
  header, the records of the copies appended: a pcap is its header and its records), and the tlog x280.

Every figure is a fresh process (`mavscope stats FILE [--json]`, start-up and dialect load included),
stdout to /dev/null, run under /usr/bin/time -v for its peak resident set size; the native engine best
of --repeat (its time, and the largest peak RSS of those runs), the pure path one run on the 1M-frame
captures (about 15-20 s each; not on 10M: it holds far more memory). The pure run's `--json` output is
kept and compared byte for byte with the native engine's (the differential tests check the same on
every bundled and real capture). Frames are counted from the `--json` totals. The load average is
printed with the results: other processes share the machine.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_capture import capture  # noqa: E402 - the bench capture's generator
from native_jsonl import CHILD_ENV, MAVSCOPE, tlog_capture  # noqa: E402

TIME = "/usr/bin/time"
PCAP_HEADER = 24


def pcap_times(src: Path, dst: Path, copies: int) -> Path:
    """`src`'s records `copies` times over behind one pcap header (cached by size)."""
    size = PCAP_HEADER + (src.stat().st_size - PCAP_HEADER) * copies
    if not dst.is_file() or dst.stat().st_size != size:
        tmp = dst.with_suffix(".tmp")
        with open(src, "rb") as f, open(tmp, "wb") as out:
            out.write(f.read(PCAP_HEADER))
            for _ in range(copies):
                f.seek(PCAP_HEADER)
                while chunk := f.read(1 << 24):
                    out.write(chunk)
        tmp.replace(dst)
    return dst


def run(path: Path, pure: bool, json: bool, keep: Path | None = None) -> tuple[float, int]:
    """(seconds, peak RSS in KiB) of one `mavscope stats` (its stdout to /dev/null, or to `keep`)."""
    env = dict(CHILD_ENV)
    if pure:
        env["MAVSCOPE_PURE"] = "1"
    argv = [TIME, "-v", MAVSCOPE, "stats", str(path), *(["--json"] if json else [])]
    with open(keep or os.devnull, "wb") as out:
        proc = subprocess.run(argv, stdout=out, stderr=subprocess.PIPE, env=env, check=True, text=True)
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (?:(\d+):)?(\d+):([\d.]+)", proc.stderr)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    assert wall is not None and rss is not None, proc.stderr
    seconds = int(wall.group(1) or 0) * 3600 + int(wall.group(2)) * 60 + float(wall.group(3))
    return seconds, int(rss.group(1))


def frames_of(path: Path) -> int:
    import json

    out = subprocess.run([MAVSCOPE, "stats", str(path), "--json"], capture_output=True, env=CHILD_ENV, check=True)
    return int(json.loads(out.stdout)["totals"]["frames"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5, help="runs of the native engine per figure (best kept)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out")
    ap.add_argument("--big-out", type=Path, default=None, help="where the 10M-frame captures go (default --out)")
    ap.add_argument("--skip-pure", action="store_true", help="skip the pure path (about 15-20 s a run)")
    ap.add_argument("--skip-10m", action="store_true", help="skip the 10M-frame captures (1.3 GB)")
    ap.add_argument("--tlog-copies", type=int, default=28)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    big = args.big_out or args.out
    big.mkdir(parents=True, exist_ok=True)
    bench, _truth = capture(args.out, 1_000_000)
    captures = [("bench pcap", bench, True)]
    tlog = tlog_capture(args.out, args.tlog_copies)
    if tlog is not None:
        captures.append((f"ardusub tlog x{args.tlog_copies}", tlog, True))
    if not args.skip_10m:
        captures.append(("bench pcap x10", pcap_times(bench, big / "bench_10m.pcap", 10), False))
        if tlog is not None:
            captures.append((f"ardusub tlog x{args.tlog_copies * 10}", tlog_capture(big, args.tlog_copies * 10),
                             False))
    version = subprocess.run([MAVSCOPE, "--version"], capture_output=True, text=True, env=CHILD_ENV).stdout.strip()
    print(f"{version}; {platform.python_version()}; {os.cpu_count()} CPUs; load average before "
          f"{os.getloadavg()[0]:.2f}")
    print()
    print("| capture | engine | output | seconds (best) | frames/s | peak RSS MB |")
    print("|---|---|---|---:|---:|---:|")
    same = []
    for label, path, with_pure in captures:
        assert path is not None
        frames = frames_of(path)
        for json in (False, True):
            runs = [run(path, False, json) for _ in range(args.repeat)]
            best = min(s for s, _ in runs)
            rss = max(k for _, k in runs) / 1024
            output = "--json" if json else "text"
            print(f"| {label} ({frames:,} frames) | native | {output} | {best:.2f} | {frames / best:,.0f} | "
                  f"{rss:.0f} |", flush=True)
            if with_pure and not args.skip_pure:
                with tempfile.TemporaryDirectory() as tmp:
                    pure_out, native_out = Path(tmp) / "pure", Path(tmp) / "native"
                    seconds, kib = run(path, True, json, keep=pure_out)
                    run(path, False, json, keep=native_out)
                    same.append((label, output, pure_out.read_bytes() == native_out.read_bytes()))
                print(f"| {label} ({frames:,} frames) | pure-python | {output} | {seconds:.2f} | "
                      f"{frames / seconds:,.0f} | {kib / 1024:.0f} |", flush=True)
    for label, output, equal in same:
        print(f"{label} {output}: native output {'identical to' if equal else 'DIFFERS from'} the pure path's")
    print(f"\nload average after {os.getloadavg()[0]:.2f}")
    return 0 if all(equal for _, _, equal in same) else 1


if __name__ == "__main__":
    sys.exit(main())
