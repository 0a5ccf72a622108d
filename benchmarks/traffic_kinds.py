#!/usr/bin/env python3
"""Issue 36's targets on seven kinds of traffic, whole process, side by side with the pymavlink baseline.

    .venv/bin/python benchmarks/traffic_kinds.py [--frames N] [--repeat N] [--kinds K,...] [--pure] [--write-doc]

The captures (N frames each, default 200,000) are traffic_gen.py's: clean UDP, one sender signing 1 frame
in 4, a signed vehicle with a MAVLink v1 ground station, 3% bad CRC, MAVLink over TCP, tlog, raw serial
with line noise; generated once, deterministically, and cached in benchmarks/out/ (git-ignored).

Each figure is a fresh process of the repository's `.venv/bin/mavscope` (start-up and dialect load
included), stdout to a file in benchmarks/out/kinds_run/, best wall time of --repeat runs:
`read F -T jsonl`, `read F` (summary lines), `read F -T jsonl --key hex:KEY` (the signed kinds),
`stats F --json` under /usr/bin/time -v for its peak resident set (the largest of the runs), `read F -T
fields` with six fields (FIELDS). The
baseline is pymavlink doing the same job as `read -T jsonl`: MAVLink.parse_buffer (robust parsing) and
json.dumps(msg.to_dict()) per message to a file; benchmarks/baselines.py's `struct` loop for the UDP
pcaps, this script's `--baseline tcp|tlog|raw` for the others (each direction's TCP payloads in capture
order, the tlog's frames one by one, the raw stream in 64 KiB chunks). With --pure every mavscope
command also runs once with MAVSCOPE_PURE=1; its output must be byte for byte the native engine's.

Every output is checked against the generator's truth, so that a run which reads nothing fails: one JSON
line (and one summary line) per complete frame and per truncated frame, `crc_status` ok / bad /
truncated as generated, every signed frame `valid` with the key, the `stats` totals likewise; the
baseline must find every frame with a good CRC (but for the frame after each truncated one, which
pymavlink's robust parsing loses: it does not look again inside the bytes of a frame cut short).
`--write-doc` replaces the block between the traffic_kinds markers in docs/performance.md.
"""

from __future__ import annotations

import argparse
import datetime
import functools
import hashlib
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
from bench_read import fmt_rate, machine, write_doc  # noqa: E402
from native_jsonl import CHILD_ENV  # noqa: E402 - buffered output, bytecode cached, engine unforced
from traffic_gen import KEY, KINDS, SIGNED_KINDS, capture  # noqa: E402

MAVSCOPE = str(ROOT / ".venv" / "bin" / "mavscope")
BASELINES = str(HERE / "baselines.py")
TIME = "/usr/bin/time"
SECTION = "## Seven kinds of traffic"
# `read -T fields`'s job: header numbers, a name, a float32 and a scaled payload field, an endpoint
FIELDS = ("-T", "fields", "-e", "frame.number", "-e", "mavlink.seq", "-e", "mavlink.msgname", "-e", "ATTITUDE.roll",
          "-e", "GLOBAL_POSITION_INT.lat", "-e", "frame.src")
BEGIN, END = "<!-- traffic_kinds:begin -->", "<!-- traffic_kinds:end -->"
LABEL = {"clean": "clean UDP", "mixsign": "1 sender signs 1 frame in 4", "signedv1": "signed vehicle + v1 GCS",
         "badcrc": "3% bad CRC", "tcp": "MAVLink over TCP", "tlog": "tlog", "raw": "raw serial, line noise"}
FAST = ("clean", "tlog")  # `read -T jsonl` at 1.5M frames/s on these, 1M on the others
PCAP_UDP = ("clean", "mixsign", "signedv1", "badcrc")

# --------------------------------------------------------------------------------------------------
# the pymavlink baselines of the kinds baselines.py does not read (run as `--baseline KIND FILE`)


def _emit(mav: Any, data: bytes, write: Any, dumps: Any) -> int:
    n = 0
    for m in mav.parse_buffer(data) or ():
        if m._type != "BAD_DATA":
            n += 1
            write(dumps(m.to_dict()) + "\n")
    return n


def baseline(kind: str, path: str) -> int:
    """pymavlink through one capture of `kind` (tcp, tlog or raw): JSON lines to stdout; frames found."""
    import mmap
    import struct

    from pymavlink.dialects.v20 import all as mavlink

    def parser() -> Any:
        mav = mavlink.MAVLink(None)
        mav.robust_parsing = True
        return mav

    write, n = sys.stdout.write, 0
    dumps = functools.partial(json.dumps, default=list)  # (a garbled frame's bytes fields: arrays)
    with open(path, "rb") as fh:
        buf = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        if kind == "raw":
            mav = parser()
            for pos in range(0, len(buf), 65_536):
                n += _emit(mav, buf[pos:pos + 65_536], write, dumps)
        elif kind == "tlog":  # 8-byte timestamp, then one frame: its length from its header
            mav, pos = parser(), 0
            while pos + 10 <= len(buf):
                stx, plen = buf[pos + 8], buf[pos + 9]
                size = 8 + plen if stx == 0xFE else 12 + plen + (13 if buf[pos + 10] & 1 else 0)
                n += _emit(mav, buf[pos + 8:pos + 8 + size], write, dumps)
                pos += 8 + size
        else:  # tcp: Ethernet/IPv4/TCP, each direction's payloads in capture order (nothing is resent)
            mavs: dict[bytes, Any] = {}
            unpack, pos = struct.Struct("<IIII").unpack_from, 24
            while pos + 16 <= len(buf):
                incl = unpack(buf, pos)[2]
                pkt = buf[pos + 16:pos + 16 + incl]
                pos += 16 + incl
                if pkt[12:14] != b"\x08\x00" or pkt[23] != 6:
                    continue
                ip = 14 + (pkt[14] & 15) * 4
                data = pkt[ip + (pkt[ip + 12] >> 4) * 4:]
                if data:
                    key = pkt[26:34] + pkt[ip:ip + 4]
                    if key not in mavs:
                        mavs[key] = parser()
                    n += _emit(mavs[key], data, write, dumps)
    return n


# --------------------------------------------------------------------------------------------------
# running and checking


def run(cmd: list[str], out: Path, repeat: int, pure: bool = False, rss: bool = False) -> tuple[float, int, str]:
    """Best wall seconds of `repeat` runs of `cmd` (stdout to `out`), the largest peak RSS in KiB (under
    /usr/bin/time -v when `rss`; 0 otherwise) and the last run's stderr."""
    env = dict(CHILD_ENV, MAVSCOPE_PURE="1") if pure else CHILD_ENV
    argv = [TIME, "-v", *cmd] if rss and os.path.exists(TIME) else cmd
    best, peak, err = float("inf"), 0, ""
    for _ in range(repeat):
        if out.exists():
            out.unlink()
            time.sleep(0.1)  # the freed blocks settle outside the timed run
        with open(out, "wb") as fh:
            t0 = time.perf_counter()
            p = subprocess.run(argv, stdout=fh, stderr=subprocess.PIPE, env=env, check=False)
            dt = time.perf_counter() - t0
        err = p.stderr.decode(errors="replace")
        if p.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}): {err[-800:]}")
        best = min(best, dt)
        if rss:
            m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", err)
            if m:
                peak = max(peak, int(m.group(1)))
            else:  # no /usr/bin/time: the largest child so far (this process's children, in KiB)
                import resource

                peak = max(peak, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    return best, peak, err


def check(what: str, got: object, want: object) -> None:
    if got != want:
        raise SystemExit(f"sanity check failed: {what}: got {got}, expected {want}")


def check_lines(kind: str, truth: dict[str, Any], out: Path, fmt: str, key: bool = False) -> None:
    """The output of `read` against the truth: every frame shown once, each CRC and signature as made."""
    data = out.read_bytes()
    shown = truth["frames"] + truth["truncated"]
    check(f"{kind} {fmt}: lines", data.count(b"\n"), shown)
    if fmt != "jsonl":
        return
    for status, want in (("ok", truth["frames"] - truth["bad_crc"]), ("bad", truth["bad_crc"]),
                         ("truncated", truth["truncated"])):
        check(f"{kind} jsonl: crc_status {status}", data.count(b'"crc_status":"%s"' % status.encode()), want)
    if key:
        check(f"{kind} --key: valid signatures", data.count(b'"status":"valid"'), truth["signed"])


def check_fields(kind: str, truth: dict[str, Any], out: Path) -> None:
    """`-T fields` (FIELDS): a line per record, every frame's sequence number among its occurrences."""
    seqs = sum(line.split(b"\t")[1].count(b",") + 1 for line in out.read_bytes().splitlines())
    check(f"{kind} fields: mavlink.seq occurrences", seqs, truth["frames"] + truth["truncated"])


def check_stats(kind: str, truth: dict[str, Any], out: Path) -> None:
    tot = json.loads(out.read_bytes())["totals"]
    check(f"{kind} stats: frames", tot["frames"], truth["frames"] + truth["truncated"])
    check(f"{kind} stats: CRC ok", tot["crc"].get("ok", 0), truth["frames"] - truth["bad_crc"])


def digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(1 << 22):
            h.update(chunk)
    return h.hexdigest()


def measure(kind: str, path: Path, truth: dict[str, Any], args: argparse.Namespace) -> dict[str, Any]:
    """Every figure of one kind: {job: (seconds, peak KiB)} and, with --pure, {job + "_pure": ...}."""
    work = args.out / "kinds_run"
    work.mkdir(parents=True, exist_ok=True)
    jobs: dict[str, tuple[list[str], str]] = {
        "jsonl": (["read", str(path), "-T", "jsonl"], "jsonl"), "summary": (["read", str(path)], "summary"),
        "stats": (["stats", str(path), "--json"], "stats"), "fields": (["read", str(path), *FIELDS], "fields")}
    if kind in SIGNED_KINDS:
        jobs["key"] = (["read", str(path), "-T", "jsonl", "--key", "hex:" + KEY.hex()], "jsonl")
    res: dict[str, Any] = {}
    for job, (argv, fmt) in jobs.items():
        for pure in (False, True) if args.pure else (False,):
            name = job + ("_pure" if pure else "")
            out = work / f"{kind}.{name}.out"
            secs, peak, _ = run([MAVSCOPE, *argv], out, 1 if pure else args.repeat, pure, rss=job == "stats")
            if fmt == "stats":
                check_stats(kind, truth, out)
            elif fmt == "fields":
                check_fields(kind, truth, out)
            else:
                check_lines(kind, truth, out, fmt, key=job == "key")
            res[name] = (secs, peak)
            if pure:
                check(f"{kind} {job}: pure output == native output", digest(out),
                      digest(work / f"{kind}.{job}.out"))
    out = work / f"{kind}.baseline.out"
    base = [sys.executable, BASELINES, "struct", str(path)] if kind in PCAP_UDP else \
        [sys.executable, str(Path(__file__).resolve()), "--baseline", kind, str(path)]
    secs, _, err = run(base, out, args.repeat)
    m = re.search(r"frames=(\d+)", err)
    found = int(m.group(1)) if m else -1
    good = truth["frames"] - truth["bad_crc"]
    # pymavlink does not look again inside a frame cut short: it may lose the frames after each cut (a cut
    # head reads LEN bytes on, over one frame or two); the baseline is timed, not judged
    if not good - 2 * truth["truncated"] <= found <= good:
        check(f"{kind} baseline: frames with a good CRC", found, good)
    res["baseline"] = (secs, 0)
    return res


# --------------------------------------------------------------------------------------------------
# the report


def _yes(ok: bool) -> str:
    return "yes" if ok else "**no**"


def report(results: dict[str, tuple[dict[str, Any], dict[str, Any]]], args: argparse.Namespace) -> str:
    """One markdown table per target; rows = kinds."""
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    lines = [f"Generated by `benchmarks/traffic_kinds.py --frames {args.frames} --repeat {args.repeat}"
             f"{' --pure' if args.pure else ''}` on {datetime.date.today().isoformat()}, {machine()}; "
             f"load average at the end {load}. Each figure is a whole `.venv/bin/mavscope` process (start-up "
             f"included), stdout to a file, best of {args.repeat}; frames/s counts the frames shown "
             "(complete and truncated). The captures are traffic_gen.py's (see its docstring).", ""]
    pure = args.pure

    def pure_cols(r: dict[str, Any], job: str, shown: int) -> str:
        if not pure:
            return ""
        s = r[job + "_pure"][0]
        return f" {s:.2f} | {fmt_rate(shown, s)} | {s / r[job][0]:.1f}x |"

    ph = " pure s | pure frames/s | native speed-up |" if pure else ""
    pd = "---:|---:|---:|" if pure else ""
    tables = [
        ("jsonl", "`mavscope read F -T jsonl`: at least 15x the pymavlink baseline and 1M frames/s "
                  "(1.5M on clean UDP and tlog)",
         "| traffic | frames | seconds | frames/s | baseline s | x baseline | target met |" + ph,
         "|---|---:|---:|---:|---:|---:|---|" + pd),
        ("summary", "`mavscope read F` (summary lines): at least 1M frames/s",
         "| traffic | frames | seconds | frames/s | target met |" + ph, "|---|---:|---:|---:|---|" + pd),
        ("key", f"`mavscope read F -T jsonl --key hex:{KEY.hex()[:8]}...` (the right key): at least 700k "
                "frames/s", "| traffic | frames | seconds | frames/s | target met |" + ph,
         "|---|---:|---:|---:|---|" + pd),
        ("fields", f"`mavscope read F {' '.join(FIELDS)}`: at the JSON Lines speed",
         "| traffic | frames | seconds | frames/s | `-T jsonl` s | x `-T jsonl` time | target met |" + ph,
         "|---|---:|---:|---:|---:|---:|---|" + pd),
        ("stats", "`mavscope stats F --json`: at least 1M frames/s in at most 150 MB (peak RSS)",
         "| traffic | frames | seconds | frames/s | peak MB | target met |" + ph, "|---|---:|---:|---:|---:|---|" + pd),
    ]
    for job, title, head, rule in tables:
        lines += [f"**{title}**", "", head, rule]
        for kind, (truth, r) in results.items():
            if job not in r:
                continue
            shown = truth["frames"] + truth["truncated"]
            secs, peak = r[job]
            rate = shown / secs
            row = f"| {LABEL[kind]} | {shown:,} | {secs:.2f} | {fmt_rate(shown, secs)} |"
            if job == "jsonl":
                bs = r["baseline"][0]
                need = 1_500_000 if kind in FAST else 1_000_000
                row += f" {bs:.2f} | {bs / secs:.1f}x | {_yes(bs / secs >= 15 and rate >= need)} |"
            elif job == "fields":
                js = r["jsonl"][0]
                row += f" {js:.2f} | {secs / js:.2f}x | {_yes(secs <= js * 1.1)} |"
            elif job == "stats":
                mb = peak / 1024
                row += f" {mb:.0f} | {_yes(rate >= 1_000_000 and mb <= 150)} |"
            else:
                row += f" {_yes(rate >= (700_000 if job == 'key' else 1_000_000))} |"
            lines.append(row + pure_cols(r, job, shown))
        lines.append("")
    if pure:
        lines.append("Every pure run's output was byte for byte the native engine's.")
    return "\n".join(lines).rstrip() + "\n"


def main() -> int:
    if len(sys.argv) == 4 and sys.argv[1] == "--baseline":
        n = baseline(sys.argv[2], sys.argv[3])
        sys.stdout.flush()
        print(f"frames={n}", file=sys.stderr)
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200_000, help="frames per capture (default 200,000)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per figure, best kept (default 3)")
    ap.add_argument("--kinds", default=",".join(KINDS), help=f"a subset of {','.join(KINDS)}")
    ap.add_argument("--out", type=Path, default=HERE / "out", help="captures and outputs (git-ignored)")
    ap.add_argument("--pure", action="store_true", help="also run each mavscope command with MAVSCOPE_PURE=1")
    ap.add_argument("--write-doc", action="store_true", help="replace the generated block in docs/performance.md")
    args = ap.parse_args()
    kinds = [k for k in args.kinds.split(",") if k]
    if unknown := set(kinds) - set(KINDS):
        ap.error(f"unknown kinds: {', '.join(sorted(unknown))}")
    results = {}
    for kind in kinds:
        path, truth = capture(kind, args.out, args.frames)
        print(f"{kind}: {path.name} ({truth['frames']:,} frames)", file=sys.stderr, flush=True)
        results[kind] = (truth, measure(kind, path, truth, args))
    text = report(results, args)
    print(text)
    if args.write_doc:
        write_doc(text, SECTION, BEGIN, END)
    return 0


if __name__ == "__main__":
    sys.exit(main())
