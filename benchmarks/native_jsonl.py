#!/usr/bin/env python3
"""Whole-process `mavscope read -T jsonl` (or the summary lines of `mavscope read`): native against pure.

    benchmarks/native_jsonl.py [--format jsonl|summary] [--key] [--repeat N] [--out DIR] [--skip-pure]
                               [--skip-baseline] [--tlog-copies N]

Captures (generated once and cached in DIR, default benchmarks/out/, git-ignored):
- the 1M-frame bench capture of bench_read.py (Ethernet/IPv4/UDP, 25% signed frames from two senders);
- a real tlog concatenated to about 1M frames: ../shared/real-captures/ardusub_log_tools_small.tlog
  repeated --tlog-copies times (28 by default; a tlog is just concatenated entries). Skipped when absent.

Every figure is a fresh process (`mavscope read FILE -T jsonl`, or `mavscope read FILE` with
`--format summary`; start-up and dialect load included),
stdout to /dev/null and to a real file in DIR (deleted before each run), best of --repeat for the native
engine (the pure path: one run). Frames are counted from the output. The pymavlink baseline is
benchmarks/baselines.py's `struct` (mmap+struct pcap loop, parse_buffer, json.dumps(to_dict())), one run.
The machine's load average is printed with the results: other processes share it.
With --key every run verifies signatures: `--key hex:<the bench capture's signing key>` (bench_capture's
SIGNING_KEY, bytes(range(32))), so the bench pcap's signed quarter is judged (valid) rather than no-key.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_capture import SIGNING_KEY, capture  # noqa: E402 - the bench capture's generator (bench_read.py too)

MAVSCOPE = str(Path(sys.executable).with_name("mavscope"))
REAL_TLOG = ROOT.parent / "shared" / "real-captures" / "ardusub_log_tools_small.tlog"
# Children run as an installed mavscope does: buffered output, bytecode cached (a shell's
# PYTHONDONTWRITEBYTECODE would recompile every module each run), the engine chosen by mavscope.
CHILD_ENV = {k: v for k, v in os.environ.items()
             if k not in ("PYTHONUNBUFFERED", "MAVSCOPE_PURE", "PYTHONDONTWRITEBYTECODE")}
FORMATS = {"jsonl": ["-T", "jsonl"], "summary": []}  # the output options of each format
KEY_OPTIONS = ["--key", "hex:" + SIGNING_KEY.hex()]  # the bench capture's signing key (--key)


def tlog_capture(out: Path, copies: int) -> Path | None:
    if not REAL_TLOG.is_file():
        return None
    path = out / f"ardusub_x{copies}.tlog"
    if not path.is_file() or path.stat().st_size != REAL_TLOG.stat().st_size * copies:
        data = REAL_TLOG.read_bytes()
        tmp = path.with_suffix(".tmp")
        with open(tmp, "wb") as f:
            for _ in range(copies):
                f.write(data)
        tmp.replace(path)
    return path


def run(capture: Path, pure: bool, target: str, fmt: str = "jsonl", extra: tuple[str, ...] = ()
        ) -> tuple[float, float]:
    """Wall seconds and CPU seconds (the child's user + system, from wait4) of one `mavscope read capture`
    in format `fmt` (and `extra` options) to `target` ("null" or a file path)."""
    env = dict(CHILD_ENV)
    if pure:
        env["MAVSCOPE_PURE"] = "1"
    if target != "null" and os.path.exists(target):
        os.unlink(target)
        time.sleep(0.2)  # let the file system settle the freed blocks outside the timed run
    with open(os.devnull if target == "null" else target, "wb") as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen([MAVSCOPE, "read", str(capture), *FORMATS[fmt], *extra], stdout=out, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise SystemExit(f"mavscope exited with {proc.returncode}")
        return wall, usage.ru_utime + usage.ru_stime


def count_lines(capture: Path, pure: bool = False, fmt: str = "jsonl", extra: tuple[str, ...] = ()) -> int:
    env = dict(CHILD_ENV)
    if pure:
        env["MAVSCOPE_PURE"] = "1"
    proc = subprocess.Popen([MAVSCOPE, "read", str(capture), *FORMATS[fmt], *extra], stdout=subprocess.PIPE,
                            env=env)
    assert proc.stdout is not None
    n = 0
    while chunk := proc.stdout.read(1 << 20):
        n += chunk.count(b"\n")
    proc.wait()
    return n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--format", choices=sorted(FORMATS), default="jsonl",
                    help="the output: JSON Lines (-T jsonl) or the summary lines (default jsonl)")
    ap.add_argument("--key", action="store_true",
                    help="verify signatures with the bench capture's signing key (--key hex:...)")
    ap.add_argument("--repeat", type=int, default=5, help="runs of the native engine per figure (best kept)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out")
    ap.add_argument("--skip-pure", action="store_true", help="skip the pure-Python path (about 12 s a run)")
    ap.add_argument("--skip-baseline", action="store_true", help="skip the pymavlink baseline (about 25 s)")
    ap.add_argument("--tlog-copies", type=int, default=28)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    bench, truth = capture(args.out, 1_000_000)
    captures = [("bench pcap (1M frames, 25% signed)", bench)]
    tlog = tlog_capture(args.out, args.tlog_copies)
    if tlog is not None:
        captures.append((f"{REAL_TLOG.name} x{args.tlog_copies}", tlog))
    version = subprocess.run([MAVSCOPE, "--version"], capture_output=True, text=True, env=CHILD_ENV).stdout.strip()
    extra = tuple(KEY_OPTIONS) if args.key else ()
    print(f"{version}; {platform.python_version()}; {os.cpu_count()} CPUs; format {args.format}"
          f"{'; --key (the bench capture key)' if args.key else ''}; load average before {os.getloadavg()[0]:.2f}")
    print()
    print("| capture | engine | output | seconds (best) | frames/s | CPU s (that run) |")
    print("|---|---|---|---:|---:|---:|")
    results: dict[tuple[str, str, str], float] = {}
    for label, path in captures:
        frames = count_lines(path, fmt=args.format, extra=extra)
        target_file = str(args.out / f"native_{args.format}.out")
        for engine in ("native", "pure-python"):
            if engine == "pure-python" and args.skip_pure:
                continue
            repeat = args.repeat if engine == "native" else 1
            for target in ("null", target_file):
                best, cpu = min(run(path, engine == "pure-python", target, args.format, extra) for _ in range(repeat))
                results[(label, engine, target)] = best
                where = "/dev/null" if target == "null" else "file"
                print(f"| {label} ({frames:,} frames) | {engine} | {where} | {best:.2f} | {frames / best:,.0f} "
                      f"| {cpu:.2f} |", flush=True)
        if os.path.exists(target_file):
            os.unlink(target_file)
    if not args.skip_baseline:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, str(ROOT / "benchmarks" / "baselines.py"), "struct", str(bench)],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=CHILD_ENV, check=True)
        base = time.perf_counter() - t0
        frames = truth["frames"]
        print()
        print(f"pymavlink baseline on the bench pcap: {base:.2f} s, {frames / base:,.0f} frames/s")
        for target, where in (("null", "/dev/null"), (str(args.out / f"native_{args.format}.out"), "file")):
            nat = results.get((captures[0][0], "native", target))
            if nat:
                print(f"native to {where}: {base / nat:.1f}x the pymavlink baseline")
    print(f"\nload average after {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
