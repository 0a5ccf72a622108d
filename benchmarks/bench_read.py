#!/usr/bin/env python3
"""Read-throughput benchmark: `mavscope read` against pymavlink and tshark + Lua on one capture.

    benchmarks/bench_read.py [--frames N] [--out DIR] [--skip-tshark] [--write-doc]

1. Generates, deterministically and cached in DIR (default benchmarks/out/, git-ignored), an N-frame
   (default 1,000,000) Ethernet/IPv4/UDP pcap: a vehicle (1/1, :14580) and a GCS (255/190, :14550)
   exchanging a telemetry mix, mostly one frame per datagram, ~10% of vehicle datagrams carrying 2-3
   frames (as mavlink-router does); a quarter of the datagrams come from two other senders (vehicle
   2/1, GCS 254/190) that sign every frame, as signing is set up per link. Frames are packed by pymavlink.
2. Times, each in a fresh subprocess (start-up included), as MAVLink frames per wall-clock second:
   `mavscope read -T jsonl`, `mavscope read` (summary), a pymavlink baseline (struct pcap loop +
   MAVLink.parse_buffer + json.dumps(msg.to_dict())), the same baseline with scapy's PcapReader,
   tshark + pymavlink's Lua dissector on a slice and mavscope on that slice.
3. Measures the layers in-process (record iteration, decapsulation, framing, JSON), the CRC
   implementations, the pcap readers, and profiles the JSONL path with cProfile.
Prints markdown; --write-doc replaces the "Reading captures" section of docs/performance.md.

The pymavlink baselines run as subprocesses of benchmarks/baselines.py.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import random
import re
import shutil
import struct
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_capture import GEN_VERSION, capture, write_slice  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
BASELINES = str(Path(__file__).resolve().parent / "baselines.py")
SLICE_FRAMES = 20_000
PY = sys.executable
# Subprocesses run without PYTHONUNBUFFERED (some CI/containers set it; it turns every write of mavscope
# and of the baseline into a write(2) call, ~0.6 s per 1M lines); the doc records whether it was set.
# the children run as a user's would: buffered output, compiled modules cached (PYTHONDONTWRITEBYTECODE,
# set in some sandboxes, would make every child compile mavscope afresh: 0.1-0.2 s of start-up)
CHILD_ENV = {k: v for k, v in os.environ.items() if k not in ("PYTHONUNBUFFERED", "PYTHONDONTWRITEBYTECODE")}

# --------------------------------------------------------------------------------------------------
# measuring


def timed(cmd: list[str], repeat: int = 1, env: dict | None = None, stdout=subprocess.DEVNULL) -> tuple[float, str]:
    """Best wall-clock seconds of `repeat` runs of `cmd` (stdout to /dev/null) and the last stderr."""
    best, err = float("inf"), ""
    for _ in range(repeat):
        t0 = time.perf_counter()
        p = subprocess.run(cmd, stdout=stdout, stderr=subprocess.PIPE, env=env or CHILD_ENV, check=False)
        dt = time.perf_counter() - t0
        err = p.stderr.decode(errors="replace")
        if p.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}): {err[-500:]}")
        best = min(best, dt)
    return best, err


def best_of(fn, repeat: int = 3) -> tuple[float, object]:
    best, res = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = fn()
        best = min(best, time.perf_counter() - t0)
    return best, res


def stages(path: Path) -> tuple[list[tuple[str, float, int]], float, int]:
    """Cumulative layers in-process: (name, seconds, frames) rows, dialect load seconds, frame count."""
    from mavscope.capture.detect import open_capture
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.output.jsonout import jsonl_bytes
    from mavscope.output.text import summary_line
    from mavscope.pipeline.dissect import Dissector
    from mavscope.transport.decap import Decapsulator

    t0 = time.perf_counter()
    dialect = load_dialect([])
    t_dialect = time.perf_counter() - t0

    def records():
        with open_capture(path) as r:
            return sum(1 for _ in r)

    def decap():
        feed = Decapsulator().feed
        n = 0
        with open_capture(path) as r:
            for rec in r:
                n += len(feed(rec))
        return n

    def framing():
        with open_capture(path) as r:
            return sum(1 for _ in Dissector(dialect).run(r))

    def to_json():
        n = 0
        with open_capture(path) as r:
            for item in Dissector(dialect).run(r):
                jsonl_bytes(item)
                n += 1
        return n

    def to_summary():
        n, t0 = 0, None
        with open_capture(path) as r:
            for item in Dissector(dialect).run(r):
                if t0 is None:
                    t0 = item.time
                summary_line(item, dialect, t0)
                n += 1
        return n

    rows = []
    frames = 0
    for name, fn, rep in (("pcap records (open_capture)", records, 3),
                          ("+ decapsulation (Decapsulator.feed)", decap, 3),
                          ("+ framing, CRC, Frame (Dissector.run)", framing, 3),
                          ("+ JSON (jsonl_bytes), no write", to_json, 2),
                          ("+ summary (summary_line) instead of JSON", to_summary, 2)):
        dt, n = best_of(fn, rep)
        if "Dissector" in name:
            frames = n
        rows.append((name, dt, n))
    return rows, t_dialect, frames


def crc_micro() -> list[tuple[str, float]]:
    import timeit

    from fastcrc import crc16
    from pymavlink.generator import mavcrc

    frame = bytes(random.Random(1).randrange(256) for _ in range(40))
    body = frame[1:38]
    mc = crc16.mcrf4xx
    cands = [
        ("fastcrc crc16.mcrf4xx (ours: 2 calls, + crc_extra)", lambda: mc(bytes((7,)), mc(body))),
        ("pymavlink x25crc (= x25crc_fast, wraps fastcrc)", lambda: mavcrc.x25crc(body).accumulate(b"\x07")),
        ("pymavlink x25crc_slow (pure Python)", lambda: mavcrc.x25crc_slow(body).accumulate(b"\x07")),
    ]
    assert mc(bytes((7,)), mc(body)) == mavcrc.x25crc_slow(body + b"\x07").crc
    try:
        import crcmod  # type: ignore[import-not-found]

        f = crcmod.mkCrcFun(0x11021, initCrc=0xFFFF, rev=True, xorOut=0)
        cands.append(("crcmod mkCrcFun(0x11021, rev)", lambda: f(body + b"\x07")))
    except ImportError:
        cands.append(("crcmod", float("nan")))
    out = []
    for name, fn in cands:
        if not callable(fn):
            out.append((name + " (not installed)", fn))
            continue
        num = 20000 if "slow" in name else 200000
        best = min(timeit.repeat(fn, number=num, repeat=3)) / num
        out.append((name, best * 1e6))
    return out


def reader_micro(path: Path) -> list[tuple[str, float, int]]:
    import mmap

    from mavscope.capture.detect import open_capture

    def ours():
        with open_capture(path) as r:
            return sum(1 for _ in r)

    def bare_mmap():
        n = 0
        with open(path, "rb") as fh:
            buf = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
            unpack = struct.Struct("<IIII").unpack_from
            pos, size = 24, len(buf)
            while pos + 16 <= size:
                _, _, incl, _ = unpack(buf, pos)
                buf[pos + 16 : pos + 16 + incl]
                pos += 16 + incl
                n += 1
        return n

    def bare_read():
        n = 0
        with open(path, "rb") as fh:
            fh.read(24)
            unpack = struct.Struct("<IIII").unpack
            read = fh.read
            while True:
                h = read(16)
                if len(h) < 16:
                    return n
                read(unpack(h)[2])
                n += 1

    def scapy_raw():
        from scapy.utils import RawPcapReader

        with RawPcapReader(str(path)) as r:
            return sum(1 for _ in r)

    rows = []
    for name, fn in (("mavscope PcapReader (mmap + struct, Record tuples)", ours),
                     ("bare loop: mmap + struct.unpack_from + slice", bare_mmap),
                     ("bare loop: buffered file.read + struct", bare_read),
                     ("scapy RawPcapReader", scapy_raw)):
        dt, n = best_of(fn, 2)
        rows.append((name, dt, n))
    try:
        import dpkt  # type: ignore[import-not-found]

        def dpkt_reader():
            with open(path, "rb") as fh:
                return sum(1 for _ in dpkt.pcap.Reader(fh))

        dt, n = best_of(dpkt_reader, 2)
        rows.append(("dpkt pcap.Reader", dt, n))
    except ImportError:
        rows.append(("dpkt (not installed)", float("nan"), 0))
    return rows


def profile_jsonl(path: Path, top: int = 12) -> str:
    code = (
        "import cProfile, pstats, io, sys\n"
        "from mavscope.cli import main\n"
        "pr = cProfile.Profile(); pr.enable()\n"
        f"main(['read', {str(path)!r}, '-T', 'jsonl'])\n"
        "pr.disable(); s = io.StringIO()\n"
        f"pstats.Stats(pr, stream=s).sort_stats('tottime').print_stats({top}); sys.stderr.write(s.getvalue())\n"
    )
    _, err = timed([PY, "-c", code])
    lines = err.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().startswith("ncalls"))
    return "\n".join(lines[start - 4 : start + top + 1])


def tshark_run(out_dir: Path, slice_path: Path) -> tuple[list[tuple[str, float, int]], str] | None:
    sys.path.insert(0, str(ROOT))
    from tests.support.tshark import (
        TsharkUnavailable,
        _tshark_env,
        check_lua_loads,
        find_tshark,
        generate_lua_dissector,
    )

    try:
        exe = find_tshark()
        lua_dir = out_dir / "lua"
        lua_dir.mkdir(exist_ok=True)
        lua = lua_dir / "mavlink_all.lua"
        if not lua.is_file():
            lua = generate_lua_dissector(lua_dir)
        check_lua_loads(exe, lua)
    except TsharkUnavailable as exc:
        print(f"tshark skipped: {exc}", file=sys.stderr)
        return None
    env = _tshark_env(lua_dir)
    version = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    base = [exe, "-n", "-X", f"lua_script:{lua}", "-r", str(slice_path)]
    rows = []
    # count the frames the Lua decoded: one msgid occurrence per MAVLink subtree
    p = subprocess.run(base + ["-T", "fields", "-E", "occurrence=a", "-e", "mavlink_proto.msgid"],
                       capture_output=True, env=env, check=False)
    lua_frames = sum(len([x for x in line.split(b",") if x]) for line in p.stdout.splitlines())
    for label, extra in (("-T fields -e frame.number -e mavlink_proto.msgid -e mavlink_proto.sequence",
                          ["-T", "fields", "-e", "frame.number", "-e", "mavlink_proto.msgid", "-e",
                           "mavlink_proto.sequence"]),
                         ("-T ek", ["-T", "ek"])):
        dt, _ = timed(base + extra, repeat=2, env=env)
        rows.append((f"tshark + Lua `{label}`", dt, lua_frames))
    return rows, version


# --------------------------------------------------------------------------------------------------
# report


def fmt_rate(frames: int, seconds: float) -> str:
    return f"{frames / seconds:,.0f}" if seconds == seconds and seconds > 0 else "n/a"


def machine() -> str:
    cpu = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{os.cpu_count()} CPUs (`nproc` {os.cpu_count()}), {cpu}, Python {platform.python_version()}, "
            f"{platform.system()} {platform.release()}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1_000_000)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "out")
    ap.add_argument("--skip-tshark", action="store_true")
    ap.add_argument("--skip-scapy", action="store_true", help="skip the slow pymavlink + scapy baseline")
    ap.add_argument("--write-doc", action="store_true", help="write the report into docs/performance.md")
    args = ap.parse_args()

    t_start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    log = lambda *a: print(*a, file=sys.stderr, flush=True)  # noqa: E731
    path, truth = capture(args.out, args.frames)
    N = truth["frames"]
    log(f"capture {path} ({path.stat().st_size / 1e6:.0f} MB): {truth}")
    mav = shutil.which("mavscope", path=str(Path(PY).parent)) or "mavscope"

    rows: list[tuple[str, float, int]] = []  # (what, seconds, frames)
    log("mavscope -T jsonl ...")
    dt, _ = timed([mav, "read", str(path), "-T", "jsonl"], repeat=3)
    rows.append(("`mavscope read FILE -T jsonl`", dt, N))
    t_jsonl = dt
    log("mavscope summary ...")
    dt, _ = timed([mav, "read", str(path)], repeat=3)
    rows.append(("`mavscope read FILE` (summary lines)", dt, N))
    log("pymavlink baseline (struct) ...")
    dt, err = timed([PY, BASELINES, "struct", str(path)], repeat=1)
    n_base = int(re.search(r"frames=(\d+)", err).group(1))
    rows.append(("pymavlink baseline: mmap+struct pcap loop, parse_buffer, json.dumps(to_dict())", dt, n_base))
    t_base = dt

    log("stages ...")
    stage_rows, t_dialect, n_ours = stages(path)
    log("readers, crc ...")
    reader_rows = reader_micro(path)
    crc_rows = crc_micro()
    log("profile ...")
    prof = profile_jsonl(path)

    slice_rows: list[tuple[str, float, int]] = []
    tshark_version = ""
    slice_path = args.out / f"slice_{SLICE_FRAMES}_of_{args.frames}_v{GEN_VERSION}.pcap"
    n_slice = write_slice(path, slice_path, SLICE_FRAMES)
    res = None
    if not args.skip_tshark:
        log("tshark ...")
        res = tshark_run(args.out, slice_path)
        if res is not None:
            slice_rows += res[0]
            tshark_version = res[1]
    dt, _ = timed([mav, "read", str(slice_path), "-T", "jsonl"], repeat=3)
    slice_rows.append(("`mavscope read SLICE -T jsonl`", dt, n_slice))
    dt, _ = timed([mav, "read", str(slice_path)], repeat=3)
    slice_rows.append(("`mavscope read SLICE` (summary)", dt, n_slice))
    dt, _ = timed([PY, BASELINES, "struct", str(slice_path)], repeat=3)
    slice_rows.append(("pymavlink baseline (mmap+struct) on SLICE", dt, n_slice))
    if not args.skip_scapy:
        # scapy dissects every packet (~2.5k packets/s): a 1M-frame run would take ~7 minutes alone
        log("pymavlink + scapy baseline on the slice ...")
        dt, err = timed([PY, BASELINES, "scapy", str(slice_path)], repeat=1)
        n_scapy = int(re.search(r"frames=(\d+)", err).group(1))
        slice_rows.append(("pymavlink + scapy `PcapReader` on SLICE (typical script; 1 run)", dt, n_scapy))

    ratio = t_base / t_jsonl
    L = []
    L.append(f"Command: `{' '.join(['benchmarks/bench_read.py'] + sys.argv[1:])}`  ")
    L.append(f"Machine: {machine()}  ")
    L.append(f"Date: {datetime.date.today().isoformat()}; whole run {time.perf_counter() - t_start:.0f} s; "
             "children run with PYTHONUNBUFFERED unset "
             f"(it was {'set' if 'PYTHONUNBUFFERED' in os.environ else 'unset'} "
             "in the calling shell)")
    L.append("")
    L.append(f"Capture: {N:,} MAVLink frames in {truth['datagrams']:,} Ethernet/IPv4/UDP datagrams "
             f"({path.stat().st_size / 1e6:.0f} MB), {truth['signed']:,} signed "
             f"({100 * truth['signed'] / N:.1f}%), {len(truth['types'])} message types; "
             f"generated with pymavlink in {truth.get('generate_s', '?')} s (cached).")
    L.append(f"Frames seen: truth {N:,}, mavscope {n_ours:,}, pymavlink baseline {n_base:,}"
             + (" (all equal)." if N == n_ours == n_base else " (MISMATCH)."))
    L.append("")
    L.append("### Whole file, fresh process each (start-up included; best of 3, the pymavlink baseline 1 run)")
    L.append("")
    L.append("| what | seconds | frames/s | vs pymavlink baseline |")
    L.append("|---|---:|---:|---:|")
    for what, dt, n in rows:
        L.append(f"| {what} | {dt:.2f} | {fmt_rate(n, dt)} | {t_base / dt:.1f}x |")
    L.append("")
    verdict = "meets" if ratio >= 10 else f"misses (by a factor of {10 / ratio:.2f})"
    L.append(f"**JSON Lines vs pymavlink baseline: {ratio:.1f}x. Target >= 10x: {verdict}.**")
    L.append("")
    if slice_rows:
        L.append(f"### Slice: first {n_slice:,} frames, fresh process each "
                 f"({tshark_version or 'tshark skipped'}; best of 2-3)")
        L.append("")
        L.append("| what | seconds | frames/s |")
        L.append("|---|---:|---:|")
        for what, dt, n in slice_rows:
            L.append(f"| {what} | {dt:.2f} | {fmt_rate(n, dt)} |")
        L.append("")
    L.append("### Where the time goes: cumulative layers in one process "
             f"(dialect load {t_dialect:.2f} s, not included)")
    L.append("")
    L.append("| stage | seconds | items | frames/s |")
    L.append("|---|---:|---:|---:|")
    for what, dt, n in stage_rows:
        L.append(f"| {what} | {dt:.2f} | {n:,} | {fmt_rate(N, dt)} |")
    L.append("")
    L.append("### CRC (one 40-byte frame: 37 bytes + CRC_EXTRA)")
    L.append("")
    L.append("| implementation | us/frame |")
    L.append("|---|---:|")
    for what, us in crc_rows:
        L.append(f"| {what} | {us:.3f} |" if us == us else f"| {what} | n/a |")
    L.append("")
    L.append(f"### pcap record readers (whole file, {truth['datagrams']:,} records, best of 2)")
    L.append("")
    L.append("| reader | seconds | records/s |")
    L.append("|---|---:|---:|")
    for what, dt, n in reader_rows:
        L.append(f"| {what} | {dt:.2f} | {fmt_rate(n, dt)} |" if n else f"| {what} | n/a | n/a |")
    L.append("")
    L.append("### cProfile of `mavscope read FILE -T jsonl` (top 12 by tottime)")
    L.append("")
    L.append("```")
    L.append(prof)
    L.append("```")
    report = "\n".join(L)
    print(report)
    if args.write_doc:
        write_doc(report)
    return 0


SECTION = "## Reading captures"
MARK_BEGIN = "<!-- bench_read:begin (generated by benchmarks/bench_read.py --write-doc) -->"
MARK_END = "<!-- bench_read:end -->"


def write_doc(report: str, section: str = SECTION, begin: str = MARK_BEGIN, end: str = MARK_END) -> None:
    """Replace the generated block (between `begin` and `end`) inside `section` of docs/performance.md,
    creating either if missing ("Reading captures" by default; bench_export writes its own)."""
    text = DOC.read_text() if DOC.is_file() else "# Performance\n"
    block = f"{begin}\n{report}\n{end}"
    if begin in text and end in text:
        a = text.index(begin)
        b = text.index(end) + len(end)
        text = text[:a] + block + text[b:]
    elif section in text:
        a = text.index(section) + len(section)
        text = text[:a] + "\n\n" + block + "\n" + text[a:]
    else:
        text = text.rstrip("\n") + f"\n\n{section}\n\n{block}\n"
    DOC.write_text(text)


if __name__ == "__main__":
    sys.exit(main())
