#!/usr/bin/env python3
"""Live-capture load benchmark: `mavscope live --udp` against a paced pymavlink sender on loopback.

    benchmarks/bench_live.py [--rate 20000] [--seconds 60] [--step] [--step-seconds 10] [--write-doc]

The sender (a subprocess of this script) pre-encodes a telemetry mix with pymavlink (HEARTBEATs from
systems 1-3, STATUSTEXT from system 100, ATTITUDE, GLOBAL_POSITION_INT, SYS_STATUS, v2, one frame per
datagram) and sends the bytes with a plain UDP socket, paced per millisecond: pymavlink's own `mav.send`
packs each message in Python and cannot reach 20,000/s on its own.

Each run starts `mavscope live --udp 127.0.0.1:PORT` in a fresh process with stdout to a file, sends for
the given time, waits until mavscope's output holds every frame sent (or 10 s more), stops it with
SIGTERM and reads its summary line. Reported per run: frames sent, frames in the output, kernel and
queue drops (from the summary), catch-up time after the sender stopped (a backlog in the queue shows
here before it becomes loss), mavscope's CPU time per frame and peak RSS (VmHWM).

`--step` also steps the rate up (with JSON Lines and with -q) to find the highest rate held without
loss and with under 1 s of catch-up. `--write-doc` replaces the generated block of the "Live capture"
section of docs/performance.md.

Hidden mode used by the sender subprocess: --send PORT RATE SECONDS.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
PY = sys.executable
MAVSCOPE = [PY, "-m", "mavscope"]
CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}
CYCLE = 256 * 100  # frames pre-encoded (a multiple of 256 per sender keeps sequence numbers continuous)
SUMMARY = re.compile(r"live: (\d+) frames, (\d+) bytes, (\d+) dropped \((\d+) queue, (\d+|unknown) kernel\)")


# --------------------------------------------------------------------------------------------------
# sender


def encode_frames() -> list[bytes]:
    """CYCLE datagrams of pre-encoded v2 frames: a vehicle's telemetry mix plus other systems."""
    from pymavlink.dialects.v20 import all as v2

    vehicle = v2.MAVLink(None, srcSystem=1, srcComponent=1)
    others = [v2.MAVLink(None, srcSystem=s, srcComponent=1) for s in (2, 3)]
    text = v2.MAVLink(None, srcSystem=100, srcComponent=1)
    out: list[bytes] = []
    i = 0
    while len(out) < CYCLE:
        k = i % 10
        if k == 0:
            out.append(vehicle.heartbeat_encode(2, 12, 81, 0, 4, 3).pack(vehicle))
        elif k == 1:
            m = others[(i // 10) % 2]
            out.append(m.heartbeat_encode(6, 8, 0, 0, 4, 3).pack(m))
        elif k == 2:
            out.append(text.statustext_encode(6, f"load test {i}".encode()).pack(text))
        elif k in (3, 4, 5, 6):
            out.append(vehicle.attitude_encode(i, 0.1, -0.2, 1.5, 0.01, 0.02, 0.03).pack(vehicle))
        elif k in (7, 8):
            out.append(vehicle.global_position_int_encode(i, 473977418, 85455940, 488000, 10000, 1, 2, 3, 9000)
                       .pack(vehicle))
        else:
            out.append(vehicle.sys_status_encode(0, 0, 0, 500, 12600, 1000, 80, 0, 0, 0, 0, 0, 0).pack(vehicle))
        i += 1
    return out


def send(port: int, rate: float, seconds: float) -> dict[str, float]:
    frames = encode_frames()
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4 << 20)
    s.connect(("127.0.0.1", port))
    sendb = s.send
    total = int(rate * seconds)
    n = 0
    nf = len(frames)
    start = time.perf_counter()
    errors = 0
    while n < total:
        due = min(total, int((time.perf_counter() - start) * rate) + 1)
        while n < due:
            try:
                sendb(frames[n % nf])
            except OSError:
                errors += 1
            n += 1
        time.sleep(0.0005)
    took = time.perf_counter() - start
    return {"sent": n, "seconds": took, "errors": errors}


# --------------------------------------------------------------------------------------------------
# one run


def _proc_status(pid: int) -> dict[str, int]:
    out: dict[str, int] = {}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                k, _, v = line.partition(":")
                if k in ("VmRSS", "VmHWM"):
                    out[k] = int(v.split()[0]) * 1024
    except OSError:
        pass
    return out


def _cpu_seconds(pid: int) -> float:
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return float("nan")


def _count_lines(path: Path) -> int:
    with open(path, "rb") as f:
        return sum(chunk.count(b"\n") for chunk in iter(lambda: f.read(1 << 20), b""))


def run_once(rate: float, seconds: float, extra: list[str], tmp: Path, label: str) -> dict[str, object]:
    """One mavscope process, one paced sender; returns the figures of the run."""
    out_path = tmp / f"live_{label}_{int(rate)}.out"
    cmd = MAVSCOPE + ["live", "--udp", "127.0.0.1:0", *extra]
    with open(out_path, "wb") as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.PIPE, env=CHILD_ENV, cwd=ROOT)
    assert proc.stderr is not None
    first = proc.stderr.readline().decode()
    m = re.search(r"udp 127\.0\.0\.1:(\d+)", first)
    if not m:
        proc.kill()
        raise SystemExit(f"mavscope live did not start: {first!r}")
    port = int(m.group(1))
    err_lines: list[str] = [first]
    reader = threading.Thread(target=lambda: err_lines.extend(ln.decode() for ln in proc.stderr), daemon=True)
    reader.start()
    peak_rss = 0
    stop_sampling = threading.Event()

    def sample() -> None:
        nonlocal peak_rss
        while not stop_sampling.wait(0.25):
            peak_rss = max(peak_rss, _proc_status(proc.pid).get("VmRSS", 0))

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    cpu0 = _cpu_seconds(proc.pid)
    snd = subprocess.run([PY, __file__, "--send", str(port), str(rate), str(seconds)],
                         capture_output=True, text=True, check=True, env=CHILD_ENV)
    sent_info = json.loads(snd.stdout)
    sent = int(sent_info["sent"])
    t_end = time.perf_counter()
    quiet = "-q" in extra
    catch_up = None
    if not quiet:  # wait for the output to hold every frame (what is still queued gets decoded)
        while time.perf_counter() - t_end < 10:
            if _count_lines(out_path) >= sent:
                catch_up = time.perf_counter() - t_end
                break
            time.sleep(0.05)
    else:
        time.sleep(0.5)
    status = _proc_status(proc.pid)
    cpu1 = _cpu_seconds(proc.pid)
    proc.send_signal(signal.SIGTERM)
    proc.wait(30)
    stop_sampling.set()
    sampler.join()
    reader.join(5)
    summary = next((ln for ln in err_lines if SUMMARY.search(ln)), "")
    sm = SUMMARY.search(summary)
    frames_out = int(sm.group(1)) if sm else -1
    lines = _count_lines(out_path) if not quiet else frames_out
    out_path.unlink()
    res = {
        "label": label, "rate": rate, "seconds": round(float(sent_info["seconds"]), 2), "sent": sent,
        "received": lines, "summary_frames": frames_out,
        "queue_drops": int(sm.group(4)) if sm else -1,
        "kernel_drops": (sm.group(5) if sm else "?"),
        "catch_up_s": None if catch_up is None else round(catch_up, 2),
        "cpu_us_per_frame": round((cpu1 - cpu0) / max(sent, 1) * 1e6, 1),
        "cpu_load": round((cpu1 - cpu0) / float(sent_info["seconds"]), 2),
        "peak_rss_mb": round(max(peak_rss, status.get("VmHWM", 0)) / 1e6, 1),
        "rcvbuf": (re.search(r"buffer (\d+) bytes", first) or [None, "?"])[1],
        "stderr": summary.strip(),
        "command": " ".join(["mavscope", "live", "--udp", "127.0.0.1:PORT", *extra]),
    }
    res["lossless"] = res["received"] == sent and res["queue_drops"] == 0 and res["kernel_drops"] in ("0",)
    res["held"] = bool(res["lossless"] and (quiet or (catch_up is not None and catch_up < 1.0)))
    return res


def step(start: int, step_by: int, seconds: float, extra: list[str], tmp: Path, label: str,
         limit: int = 200_000) -> tuple[list[dict[str, object]], int]:
    """Raise the rate until a run is not held; return the runs and the highest rate held."""
    runs = []
    best = 0
    rate = start
    while rate <= limit:
        r = run_once(rate, seconds, extra, tmp, label)
        print(json.dumps(r), file=sys.stderr, flush=True)
        runs.append(r)
        if not r["held"]:
            break
        best = rate
        rate += step_by
    return runs, best


# --------------------------------------------------------------------------------------------------
# where the time goes (one thread, no pacing: the cost of each step per datagram)


def breakdown(n: int = 100_000) -> list[str]:
    """Per-datagram cost of each step of the live path, cumulative, measured in this process."""

    sys.path.insert(0, str(ROOT))
    from mavscope.live.udp import UdpSource, parse_endpoint
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.output.jsonout import jsonl_bytes
    from mavscope.output.text import summary_line
    from mavscope.pipeline.dissect import Dissector
    from mavscope.pipeline.options import PipelineOptions
    from mavscope.pipeline.session import build_pipeline

    frames = encode_frames()
    src = UdpSource(parse_endpoint("127.0.0.1:0", what="--udp"), rcvbuf=256 << 20)
    src.open()
    port = src.local[1]
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for i in range(n):
        tx.sendto(frames[i % len(frames)], ("127.0.0.1", port))
    t = time.perf_counter()
    got = src._take(src.sock, n + 10)  # the receiver's loop body: recvmsg, ancillary data, enqueue
    t_recv = (time.perf_counter() - t) / max(got, 1)
    src.stop()
    items = [src._q.get() for _ in range(got)]
    src.close()
    t = time.perf_counter()
    records = [src._record(i + 1, 0, it) for i, it in enumerate(items)]
    t_rec = (time.perf_counter() - t) / len(items)
    dialect = load_dialect([])
    t = time.perf_counter()
    out = list(Dissector(dialect).run(records))
    t_dis = (time.perf_counter() - t) / len(items)
    t = time.perf_counter()
    out = list(build_pipeline(PipelineOptions(), dialect, records))
    t_pipe = (time.perf_counter() - t) / len(items)
    t = time.perf_counter()
    for f in out:
        jsonl_bytes(f)
    t_json = (time.perf_counter() - t) / len(items)
    t = time.perf_counter()
    for f in out:
        summary_line(f, dialect, 0.0)
    t_text = (time.perf_counter() - t) / len(items)
    return [
        f"| step ({len(items):,} datagrams, one frame each) | us per datagram |",
        "|---|---:|",
        f"| receive: `recvmsg` + ancillary data (timestamp, drops, destination) + enqueue | {t_recv * 1e6:.1f} |",
        f"| Record with a synthesised Ethernet/IPv4/UDP header | {t_rec * 1e6:.1f} |",
        f"| dissector (decapsulation, framing, CRC, Frame) | {t_dis * 1e6:.1f} |",
        f"| whole pipeline (dissector + security stage) | {t_pipe * 1e6:.1f} |",
        f"| JSON Lines line (`jsonl_bytes`) | {t_json * 1e6:.1f} |",
        f"| summary line instead (`summary_line`) | {t_text * 1e6:.1f} |",
    ]


# --------------------------------------------------------------------------------------------------
# report


def machine() -> str:
    cpu = "?"
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), "?")
    except OSError:
        pass
    return (f"{os.cpu_count()} CPUs (`nproc` {len(os.sched_getaffinity(0))}), {cpu}, Python "
            f"{platform.python_version()}, Linux {platform.release()}")


def table(runs: list[dict[str, object]]) -> list[str]:
    rows = ["| output | rate/s | seconds | sent | in output | queue drops | kernel drops | catch-up s "
            "| CPU us/frame | CPU load | peak RSS MB | held |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in runs:
        catch_up = r["catch_up_s"] if r["catch_up_s"] is not None else "-"
        held = "yes" if r["held"] else "no"
        rows.append(f"| {r['label']} | {int(r['rate']):,} | {r['seconds']} | {r['sent']:,} | {r['received']:,} "
                    f"| {r['queue_drops']} | {r['kernel_drops']} | {catch_up} "
                    f"| {r['cpu_us_per_frame']} | {r['cpu_load']} | {r['peak_rss_mb']} | {held} |")
    return rows


def report(args: argparse.Namespace, main_runs: list[dict[str, object]], steps: dict[str, tuple[list, int]],
           took: float, breakdown_rows: list[str]) -> str:
    lines = [
        f"Command: `benchmarks/bench_live.py {' '.join(sys.argv[1:])}`  ",
        f"Machine: {machine()}  ",
        f"Date: {datetime.date.today().isoformat()}; whole run {took:.0f} s  ",
        f"Load average (1 min) before / after: {LOAD[0]:.2f} / {os.getloadavg()[0]:.2f} (other processes share "
        "the machine; the sender and mavscope take about 1.3 CPUs at 20,000/s)  ",
        f"Receive buffer granted: {main_runs[0]['rcvbuf'] if main_runs else '?'} bytes (kernel figure)",
        "",
        "Sender: one process, pre-encoded pymavlink v2 frames (HEARTBEAT from systems 1-3, STATUSTEXT from "
        "system 100, ATTITUDE, GLOBAL_POSITION_INT, SYS_STATUS), one frame per datagram, paced per "
        "millisecond, over 127.0.0.1. mavscope: `" + (main_runs[0]["command"] if main_runs else "") + "`, "
        "stdout to a file, stopped with SIGTERM once its output held every frame sent.",
        "",
        f"### {int(args.rate):,} frames/s for {args.seconds:g} s",
        "",
        *table(main_runs),
    ]
    for label, (runs, best) in steps.items():
        lines += ["", f"### Step-up, {label} ({args.step_seconds:g} s per rate): highest rate held "
                      f"**{best:,} frames/s**", "", *table(runs)]
    if breakdown_rows:
        lines += ["", "### Where the time goes (each step alone, one thread, in-process; "
                  "the pipeline row includes the dissector)", "",
                  *breakdown_rows]
    lines += ["", "\"held\": every frame sent is in the output, no queue or kernel drop, and the output "
                  "caught up within 1 s of the sender stopping (a growing backlog means the rate is not "
                  "sustainable even before the queue overflows)."]
    return "\n".join(lines) + "\n"


LOAD = [0.0]
MARK_BEGIN = "<!-- bench_live:begin (generated by benchmarks/bench_live.py --write-doc) -->"
MARK_END = "<!-- bench_live:end -->"


def write_doc(text: str) -> None:
    doc = DOC.read_text() if DOC.exists() else "# Performance\n"
    block = f"{MARK_BEGIN}\n{text}{MARK_END}"
    if MARK_BEGIN in doc and MARK_END in doc:
        head, rest = doc.split(MARK_BEGIN, 1)
        doc = head + block + rest.split(MARK_END, 1)[1]
    elif "## Live capture" in doc:
        head, rest = doc.split("## Live capture", 1)
        nxt = rest.find("\n## ")
        section_end = len(rest) if nxt < 0 else nxt
        doc = head + "## Live capture" + rest[:section_end].rstrip("\n") + "\n\n" + block + "\n" + rest[section_end:]
    else:
        doc = doc.rstrip("\n") + "\n\n## Live capture\n\n" + block + "\n"
    DOC.write_text(doc)


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--send":
        port, rate, seconds = int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
        print(json.dumps(send(port, rate, seconds)))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rate", type=float, default=20_000)
    ap.add_argument("--seconds", type=float, default=60)
    ap.add_argument("--step", action="store_true", help="also step the rate up to find the highest rate held")
    ap.add_argument("--step-seconds", type=float, default=10)
    ap.add_argument("--step-start", type=int, default=10_000)
    ap.add_argument("--step-by", type=int, default=5_000)
    ap.add_argument("--formats", default="jsonl,text,quiet", help="outputs for the main run (comma-separated)")
    ap.add_argument("--breakdown", action="store_true", help="also measure the cost of each step in-process")
    ap.add_argument("--write-doc", action="store_true")
    args = ap.parse_args()
    extras = {"jsonl": ["-T", "jsonl"], "text": [], "quiet": ["-q"], "jsonl+pcap": ["-T", "jsonl", "-w", "PCAP"]}
    t0 = time.perf_counter()
    LOAD[0] = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench_live_") as tmpd:
        tmp = Path(tmpd)

        def extra(name: str) -> list[str]:
            return [str(tmp / "out.pcap") if a == "PCAP" else a for a in extras[name]]

        main_runs = []
        for name in filter(None, args.formats.split(",")):
            r = run_once(args.rate, args.seconds, extra(name), tmp, name)
            print(json.dumps(r), file=sys.stderr, flush=True)
            main_runs.append(r)
        steps: dict[str, tuple[list, int]] = {}
        if args.step:
            for name in ("jsonl", "quiet"):
                steps[name] = step(args.step_start, args.step_by, args.step_seconds, extra(name), tmp, name)
    rows = breakdown() if args.breakdown else []
    text = report(args, main_runs, steps, time.perf_counter() - t0, rows)
    print(text)
    if args.write_doc:
        write_doc(text)


if __name__ == "__main__":
    main()
