#!/usr/bin/env python3
"""A real tlog of about 1M frames: `mavscope read -T jsonl` (native engine, pure path) against the C++
parser `fasttlogparser`, in one run.

    scripts/peer-venv.sh                      # once: fasttlogparser in benchmarks/out/peers
    .venv/bin/python benchmarks/peer_tlog.py [--repeat N] [--out DIR] [--tlog-copies N] [--peer PYTHON]

The tlog is ../shared/real-captures/ardusub_log_tools_small.tlog concatenated --tlog-copies times (28:
about 1M frames; native_jsonl.py makes the same file). Every figure is a fresh process, start-up
included, best of --repeat: wall seconds and the child's CPU seconds (user + system, from wait4), as
other work may share the machine (the load average is printed).

The jobs differ, and the table says how: mavscope writes every frame as a JSON line (header, CRC and
signature verdicts, every field decoded, notes) to /dev/null; fasttlogparser's `parseTLog(path)` decodes
every message with good CRC into numpy columns per message type (its whole API) and returns them; the
script then counts the rows. Frames counted: mavscope's JSON lines, fasttlogparser's rows.
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

from native_jsonl import CHILD_ENV, MAVSCOPE, tlog_capture  # noqa: E402 - the tlog and the child environment

PEER_PYTHON = ROOT / "benchmarks" / "out" / "peers" / "bin" / "python"
PEER_SCRIPT = """
import sys, fasttlogparser
messages, _ = fasttlogparser.parseTLog(sys.argv[1])
print(sum(len(next(iter(cols.values()))) for cols in messages.values() if cols))
"""


def timed(argv: list[str], env: dict[str, str], stdout: int | None) -> tuple[float, float, bytes]:
    """Wall seconds, CPU seconds (user + system) of the child, and its stdout when `stdout` is a pipe."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, env=env, stdout=stdout, stderr=subprocess.DEVNULL)
    out = proc.stdout.read() if proc.stdout is not None else b""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{argv[0]} exited with {proc.returncode}")
    return wall, usage.ru_utime + usage.ru_stime, out


def best(repeat: int, argv: list[str], env: dict[str, str], stdout: int | None) -> tuple[float, float, bytes]:
    runs = [timed(argv, env, stdout) for _ in range(repeat)]
    return min(runs, key=lambda r: r[0])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out")
    ap.add_argument("--tlog-copies", type=int, default=28)
    ap.add_argument("--peer", type=Path, default=PEER_PYTHON, help="a Python that imports fasttlogparser")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    tlog = tlog_capture(args.out, args.tlog_copies)
    if tlog is None:
        print("../shared/real-captures/ardusub_log_tools_small.tlog is not there: nothing to measure")
        return 1
    native_env, pure_env = dict(CHILD_ENV), dict(CHILD_ENV, MAVSCOPE_PURE="1")
    read = [MAVSCOPE, "read", str(tlog), "-T", "jsonl"]
    frames = sum(1 for _ in subprocess.run(read, env=native_env, capture_output=True, check=True).stdout.splitlines())
    rows: list[tuple[str, str, float, float, int]] = []
    wall, cpu, _ = best(args.repeat, read, native_env, subprocess.DEVNULL)
    rows.append(("mavscope read -T jsonl (native)", "every frame as a JSON line", wall, cpu, frames))
    wall, cpu, _ = timed(read, pure_env, subprocess.DEVNULL)
    rows.append(("mavscope read -T jsonl (MAVSCOPE_PURE=1, 1 run)", "every frame as a JSON line", wall, cpu, frames))
    if args.peer.is_file():
        wall, cpu, out = best(args.repeat, [str(args.peer), "-c", PEER_SCRIPT, str(tlog)], dict(CHILD_ENV),
                              subprocess.PIPE)
        rows.append(("fasttlogparser.parseTLog", "numpy columns per message type", wall, cpu, int(out.split()[-1])))
    else:
        print(f"{args.peer} not found: run scripts/peer-venv.sh for the fasttlogparser row")
    print(f"{tlog.name}: {tlog.stat().st_size:,} bytes; {platform.python_version()}; "
          f"load average {os.getloadavg()[0]:.1f}; best of {args.repeat}")
    print("| tool | output | frames | seconds | frames/s | CPU s | frames per CPU s |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name, what, wall, cpu, n in rows:
        print(f"| {name} | {what} | {n:,} | {wall:.2f} | {n / wall:,.0f} | {cpu:.2f} | {n / cpu:,.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
