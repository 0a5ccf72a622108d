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

Hidden modes used by the subprocesses: --baseline {struct,scapy} FILE.
"""

from __future__ import annotations

import argparse
import datetime
import json
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

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
GEN_VERSION = 2  # bump when the generated capture changes
SIGNED_SHARE = 0.25  # of the datagrams, from the two signing senders
SIGNING_VEHICLE_SYSID = 2
SIGNING_GCS_SYSID = 254
SLICE_FRAMES = 20_000
PY = sys.executable
# Subprocesses run without PYTHONUNBUFFERED (some CI/containers set it; it turns every write of mavscope
# and of the baseline into a write(2) call, ~0.6 s per 1M lines); the doc records whether it was set.
CHILD_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}

VEHICLE = (bytes.fromhex("020000000001"), bytes([10, 0, 0, 2]), 14580, 1, 1)
GCS = (bytes.fromhex("020000000002"), bytes([10, 0, 0, 1]), 14550, 255, 190)
SIGNING_KEY = bytes(range(32))
START = 1_700_000_000.0


# --------------------------------------------------------------------------------------------------
# capture generation


def _pools(mavlink, rng: random.Random) -> dict[str, list]:
    """A few distinct message objects per type; time/seq-like fields are varied per frame later."""
    m = mavlink
    P: dict[str, list] = {}

    def r(a, b):
        return rng.randint(a, b)

    def f(a, b):
        return rng.uniform(a, b)

    P["HEARTBEAT_V"] = [m.MAVLink_heartbeat_message(2, 12, 0x59 | (k & 0x80), r(0, 20), 4, 3) for k in range(8)]
    P["HEARTBEAT_G"] = [m.MAVLink_heartbeat_message(6, 8, 0xC0, 0, 4, 3)]
    P["SYS_STATUS"] = [m.MAVLink_sys_status_message(0x2FFFFF, 0x2FFFFF, 0x2FFF0F, r(100, 900), r(11000, 12600),
                                                    r(0, 3000), r(10, 100), 0, 0, 0, 0, 0, 0) for _ in range(16)]
    P["ATTITUDE"] = [m.MAVLink_attitude_message(0, f(-.3, .3), f(-.3, .3), f(-3.1, 3.1), f(-.1, .1), f(-.1, .1),
                                                f(-.1, .1)) for _ in range(64)]
    P["GLOBAL_POSITION_INT"] = [m.MAVLink_global_position_int_message(
        0, 473977420 + r(-5000, 5000), 85455940 + r(-5000, 5000), r(480000, 520000), r(0, 50000),
        r(-500, 500), r(-500, 500), r(-100, 100), r(0, 35999)) for _ in range(64)]
    P["GPS_RAW_INT"] = [m.MAVLink_gps_raw_int_message(
        0, 3, 473977420 + r(-5000, 5000), 85455940 + r(-5000, 5000), r(480000, 520000), r(60, 120), r(80, 200),
        r(0, 900), r(0, 35999), r(8, 16), 0, 0, 0, 0, 0, 0) for _ in range(32)]
    P["VFR_HUD"] = [m.MAVLink_vfr_hud_message(f(0, 15), f(0, 15), r(0, 359), r(0, 80), f(0, 60), f(-2, 2))
                    for _ in range(32)]
    P["SERVO_OUTPUT_RAW"] = [m.MAVLink_servo_output_raw_message(
        0, 0, *[r(1000, 2000) for _ in range(8)]) for _ in range(32)]
    P["STATUSTEXT"] = [m.MAVLink_statustext_message(6, t.encode()) for t in (
        "EKF2 IMU0 is using GPS", "Arming motors", "Mission: 3 WP", "PreArm: Hardware safety switch",
        "GPS 1: detected as u-blox at 115200 baud", "Disarming motors", "Reached command #4",
        "Throttle disarmed")]
    names = ["ATC_RAT_RLL_P", "ATC_RAT_PIT_P", "WPNAV_SPEED", "BATT_CAPACITY", "RTL_ALT", "FENCE_ENABLE",
             "INS_GYRO_FILTER", "SERIAL1_BAUD", "EK3_SRC1_POSXY", "ARMING_CHECK"]
    P["PARAM_VALUE"] = [m.MAVLink_param_value_message(n.encode(), f(0, 1000), 9, 900, k)
                        for k, n in enumerate(names)]
    P["COMMAND_LONG"] = [m.MAVLink_command_long_message(1, 1, c, 0, *p) for c, p in (
        (400, (1, 0, 0, 0, 0, 0, 0)), (22, (0, 0, 0, 0, 0, 0, 10)), (176, (1, 4, 0, 0, 0, 0, 0)),
        (511, (33, 100000, 0, 0, 0, 0, 0)), (520, (1, 0, 0, 0, 0, 0, 0)))]
    P["COMMAND_ACK"] = [m.MAVLink_command_ack_message(c, 0, 0, 0, 255, 190) for c in (400, 22, 176, 511, 520)]
    P["MISSION_ITEM_INT"] = [m.MAVLink_mission_item_int_message(
        1, 1, k, 6, 16, 0, 1, 0, 2, 0, float("nan"), 473977420 + 1000 * k, 85455940 - 700 * k, 50.0, 0)
        for k in range(16)]
    P["MISSION_COUNT"] = [m.MAVLink_mission_count_message(1, 1, 16, 0)]
    P["MISSION_REQUEST_INT"] = [m.MAVLink_mission_request_int_message(255, 190, k, 0) for k in range(16)]
    P["MISSION_ACK"] = [m.MAVLink_mission_ack_message(255, 190, 0, 0)]
    P["SYSTEM_TIME"] = [m.MAVLink_system_time_message(0, 0)]
    P["TIMESYNC"] = [m.MAVLink_timesync_message(0, 0)]
    P["BATTERY_STATUS"] = [m.MAVLink_battery_status_message(
        0, 1, 1, 3500, [4100, 4090, 4105] + [65535] * 7, r(100, 900), -1, -1, r(40, 99), 0, 0, [0, 0, 0, 0], 0, 0)
        for _ in range(8)]
    return P


# (pool, sender, weight per 100 frames): rates of a typical ArduPilot/PX4 stream set plus GCS traffic
MIX = [
    ("ATTITUDE", "V", 20), ("GLOBAL_POSITION_INT", "V", 10), ("VFR_HUD", "V", 8), ("SERVO_OUTPUT_RAW", "V", 8),
    ("SYS_STATUS", "V", 6), ("GPS_RAW_INT", "V", 8), ("HEARTBEAT_V", "V", 4), ("HEARTBEAT_G", "G", 4),
    ("BATTERY_STATUS", "V", 4), ("SYSTEM_TIME", "V", 3), ("TIMESYNC", "G", 3), ("STATUSTEXT", "V", 2),
    ("PARAM_VALUE", "V", 7), ("COMMAND_LONG", "G", 2), ("COMMAND_ACK", "V", 2), ("MISSION_ITEM_INT", "G", 4),
    ("MISSION_COUNT", "G", 1), ("MISSION_REQUEST_INT", "V", 3), ("MISSION_ACK", "V", 1),
]
_TIME_FIELDS = ("time_boot_ms", "time_usec", "time_unix_usec", "ts1")


def _ip_checksum(hdr: bytes) -> int:
    s = sum(struct.unpack("!10H", hdr))
    s = (s & 0xFFFF) + (s >> 16)
    s = (s & 0xFFFF) + (s >> 16)
    return ~s & 0xFFFF


def generate(path: Path, frames: int, seed: int = 20240501) -> dict:
    """Write the capture; return its truth (frames, datagrams, signed frames, by message type)."""
    from pymavlink.dialects.v20 import all as mavlink

    rng = random.Random(seed)
    pools = _pools(mavlink, rng)
    names, senders, weights = zip(*MIX)
    # Signing is per sender, as on a real link: a signing vehicle (sysid 2) and a signing GCS (254) send
    # a quarter of the datagrams, every frame signed; vehicle 1 and GCS 255 never sign.
    macs = {"V": mavlink.MAVLink(None, VEHICLE[3], VEHICLE[4]), "G": mavlink.MAVLink(None, GCS[3], GCS[4])}
    signing_macs = {"V": mavlink.MAVLink(None, SIGNING_VEHICLE_SYSID, VEHICLE[4]),
                    "G": mavlink.MAVLink(None, SIGNING_GCS_SYSID, GCS[4])}
    for mav in signing_macs.values():
        mav.signing.secret_key = SIGNING_KEY
        mav.signing.link_id = 1
        mav.signing.timestamp = 280_000_000_000  # fixed: 2023-11-14 in 10 us units since 2015
        mav.signing.sign_outgoing = True
    rec = struct.Struct("<IIII")
    eth = struct.Struct("!6s6sH")
    ip = struct.Struct("!BBHHHBBH4s4s")
    udp = struct.Struct("!HHHH")
    out = bytearray(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1))
    truth = {"frames": 0, "datagrams": 0, "signed": 0, "types": {}}
    t = START
    ipid = 0
    n = 0
    choices = rng.choices
    while n < frames:
        name, who = None, None
        k = choices(range(len(MIX)), weights)[0]
        name, who = names[k], senders[k]
        count = 1
        if who == "V" and rng.random() < 0.10:
            count = rng.choice((2, 2, 3))
        count = min(count, frames - n)
        signed = rng.random() < SIGNED_SHARE
        mav = signing_macs[who] if signed else macs[who]
        payload = bytearray()
        for j in range(count):
            if j:
                k = choices(range(len(MIX)), weights)[0]
                while senders[k] != "V":
                    k = choices(range(len(MIX)), weights)[0]
                name = names[k]
            msg = rng.choice(pools[name])
            tb = int((t - START) * 1000) + 12345
            for fld in _TIME_FIELDS:
                if hasattr(msg, fld):
                    setattr(msg, fld, tb * 1000 if fld in ("time_usec", "time_unix_usec", "ts1") else tb & 0xFFFFFFFF)
            payload += msg.pack(mav)
            mav.seq = (mav.seq + 1) & 0xFF
            truth["signed"] += signed
            truth["types"][name] = truth["types"].get(name, 0) + 1
        n += count
        src, dst = (VEHICLE, GCS) if who == "V" else (GCS, VEHICLE)
        ulen = 8 + len(payload)
        ipid = (ipid + 1) & 0xFFFF
        iph = ip.pack(0x45, 0, 20 + ulen, ipid, 0x4000, 64, 17, 0, src[1], dst[1])
        iph = iph[:10] + struct.pack("!H", _ip_checksum(iph)) + iph[12:]
        pkt = eth.pack(dst[0], src[0], 0x0800) + iph + udp.pack(src[2], dst[2], ulen, 0) + payload
        sec = int(t)
        out += rec.pack(sec, int(round((t - sec) * 1e6)) % 1_000_000, len(pkt), len(pkt))
        out += pkt
        truth["datagrams"] += 1
        t += rng.expovariate(1000.0)  # ~1000 frames/s
    truth["frames"] = n
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(out)
    tmp.replace(path)
    return truth


def capture(out_dir: Path, frames: int) -> tuple[Path, dict]:
    path = out_dir / f"bench_{frames}_v{GEN_VERSION}.pcap"
    meta = path.with_suffix(".json")
    if path.is_file() and meta.is_file():
        return path, json.loads(meta.read_text())
    t0 = time.perf_counter()
    truth = generate(path, frames)
    truth["generate_s"] = round(time.perf_counter() - t0, 1)
    meta.write_text(json.dumps(truth, indent=1))
    return path, truth


def write_slice(src: Path, dst: Path, frames: int) -> int:
    """The first records of `src` holding about `frames` MAVLink frames (whole datagrams); frame count."""
    from pymavlink.dialects.v20 import all as mavlink

    buf = src.read_bytes()
    pos, got = 24, 0
    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    while pos < len(buf) and got < frames:
        incl = struct.unpack_from("<I", buf, pos + 8)[0]
        got += len(mav.parse_buffer(buf[pos + 16 + 42 : pos + 16 + incl]) or ())
        pos += 16 + incl
    dst.write_bytes(buf[:pos])
    return got


# --------------------------------------------------------------------------------------------------
# the pymavlink baselines (run as subprocesses through --baseline)


def baseline_struct(path: str) -> int:
    """A plain, fast pcap loop: mmap + struct record headers, Ethernet/IPv4/UDP checked by hand."""
    import mmap

    from pymavlink.dialects.v20 import all as mavlink

    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    parse, dumps, write = mav.parse_buffer, json.dumps, sys.stdout.write
    n = 0
    with open(path, "rb") as fh:
        buf = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        size = len(buf)
        unpack = struct.Struct("<IIII").unpack_from
        pos = 24
        while pos + 16 <= size:
            _, _, incl, _ = unpack(buf, pos)
            pkt = buf[pos + 16 : pos + 16 + incl]
            pos += 16 + incl
            if pkt[12:14] != b"\x08\x00" or pkt[23] != 17:
                continue
            msgs = parse(pkt[14 + (pkt[14] & 15) * 4 + 8 :])
            if msgs:
                for m in msgs:
                    if m._type != "BAD_DATA":
                        n += 1
                        write(dumps(m.to_dict()) + "\n")
    return n


def baseline_scapy(path: str) -> int:
    """The typical script: scapy's PcapReader (full dissection) + pymavlink."""
    from pymavlink.dialects.v20 import all as mavlink
    from scapy.layers.inet import UDP
    from scapy.utils import PcapReader

    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    n = 0
    write = sys.stdout.write
    with PcapReader(path) as pr:
        for pkt in pr:
            if UDP in pkt:
                msgs = mav.parse_buffer(bytes(pkt[UDP].payload))
                if msgs:
                    for m in msgs:
                        if m._type != "BAD_DATA":
                            n += 1
                            write(json.dumps(m.to_dict()) + "\n")
    return n


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
    from mavscope.dissect import Dissector
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.output.jsonout import jsonl_bytes
    from mavscope.output.text import summary_line
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
    from tests.tshark import TsharkUnavailable, _tshark_env, check_lua_loads, find_tshark, generate_lua_dissector

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
    ap.add_argument("--baseline", choices=("struct", "scapy"), help=argparse.SUPPRESS)
    ap.add_argument("file", nargs="?", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.baseline:
        n = (baseline_struct if args.baseline == "struct" else baseline_scapy)(args.file)
        sys.stdout.flush()
        print(f"frames={n}", file=sys.stderr)
        return 0

    t_start = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    log = lambda *a: print(*a, file=sys.stderr, flush=True)  # noqa: E731
    path, truth = capture(args.out, args.frames)
    N = truth["frames"]
    log(f"capture {path} ({path.stat().st_size / 1e6:.0f} MB): {truth}")
    mav = shutil.which("mavscope", path=str(Path(PY).parent)) or "mavscope"
    me = str(Path(__file__).resolve())

    rows: list[tuple[str, float, int]] = []  # (what, seconds, frames)
    log("mavscope -T jsonl ...")
    dt, _ = timed([mav, "read", str(path), "-T", "jsonl"], repeat=3)
    rows.append(("`mavscope read FILE -T jsonl`", dt, N))
    t_jsonl = dt
    log("mavscope summary ...")
    dt, _ = timed([mav, "read", str(path)], repeat=3)
    rows.append(("`mavscope read FILE` (summary lines)", dt, N))
    log("pymavlink baseline (struct) ...")
    dt, err = timed([PY, me, "--baseline", "struct", str(path)], repeat=1)
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
    dt, _ = timed([PY, me, "--baseline", "struct", str(slice_path)], repeat=3)
    slice_rows.append(("pymavlink baseline (mmap+struct) on SLICE", dt, n_slice))
    if not args.skip_scapy:
        # scapy dissects every packet (~2.5k packets/s): a 1M-frame run would take ~7 minutes alone
        log("pymavlink + scapy baseline on the slice ...")
        dt, err = timed([PY, me, "--baseline", "scapy", str(slice_path)], repeat=1)
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


def write_doc(report: str) -> None:
    """Replace the generated block inside the "Reading captures" section (creating either if missing)."""
    text = DOC.read_text() if DOC.is_file() else "# Performance\n"
    block = f"{MARK_BEGIN}\n{report}\n{MARK_END}"
    if MARK_BEGIN in text and MARK_END in text:
        a = text.index(MARK_BEGIN)
        b = text.index(MARK_END) + len(MARK_END)
        text = text[:a] + block + text[b:]
    elif SECTION in text:
        a = text.index(SECTION) + len(SECTION)
        text = text[:a] + "\n\n" + block + "\n" + text[a:]
    else:
        text = text.rstrip("\n") + f"\n\n{SECTION}\n\n{block}\n"
    DOC.write_text(text)


if __name__ == "__main__":
    sys.exit(main())
