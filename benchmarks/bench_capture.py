"""The benchmark capture: a deterministic N-frame Ethernet/IPv4/UDP pcap built with pymavlink, cached.

A vehicle (1/1, :14580) and a GCS (255/190, :14550) exchange a telemetry mix, mostly one frame per
datagram, ~10% of vehicle datagrams carrying 2-3 frames (as mavlink-router does); a quarter of the
datagrams come from two other senders (vehicle 2/1, GCS 254/190) that sign every frame, as signing is
set up per link. `capture(DIR, N)` generates it once into DIR (benchmarks/out/, git-ignored) with its
truth beside it; `write_slice` cuts the first records for the slow peers (tshark + Lua).
"""

from __future__ import annotations

import json
import random
import struct
import time
from pathlib import Path

GEN_VERSION = 2  # bump when the generated capture changes
SIGNED_SHARE = 0.25  # of the datagrams, from the two signing senders
SIGNING_VEHICLE_SYSID = 2
SIGNING_GCS_SYSID = 254
VEHICLE = (bytes.fromhex("020000000001"), bytes([10, 0, 0, 2]), 14580, 1, 1)
GCS = (bytes.fromhex("020000000002"), bytes([10, 0, 0, 1]), 14550, 255, 190)
SIGNING_KEY = bytes(range(32))
START = 1_700_000_000.0


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


