"""The seven kinds of traffic of issue 36's targets, generated deterministically and cached (benchmarks/out/).

One vehicle (1/1) and one ground station (255/190) exchange bench_capture.py's telemetry mix (ATTITUDE,
GLOBAL_POSITION_INT, SYS_STATUS, GPS_RAW_INT, HEARTBEAT, PARAM_VALUE, COMMAND_LONG now and then, mission
traffic, ...) at about 1,000 frames/s; pymavlink encodes and signs every frame (scripts/capgen's
`Endpoint`: signature timestamps follow the capture clock). One seeded `random.Random` per capture.

    clean     Ethernet/IPv4/UDP pcap, all v2 unsigned; ~10% of vehicle datagrams carry 2-3 frames
    mixsign   the same, but the vehicle signs 1 frame in 4 (chosen at random), the rest unsigned
    signedv1  the vehicle signs every frame; the ground station speaks MAVLink v1 (v10 dialect: no extensions)
    badcrc    clean, with 3% of the frames' last CRC byte XORed with a random non-zero byte (never two
              damaged frames in a row in a datagram: mavscope shows the first of such a pair as skipped
              bytes, not as a frame, where MAVLink's C parser would report two bad CRCs)
    tcp       clean's frames as one TCP connection (vehicle :5760, GCS :40412): handshake, each direction's
              bytes cut into segments of 48-600 bytes (1 in 10: 5-24) at arbitrary points (several frames per segment,
              frames across segments), a leftover flushed after 20 ms, pure ACKs every second segment
              received, FIN at the end
    tlog      clean's frames, each an 8-byte big-endian microsecond timestamp + the frame
    raw       clean's frames as one serial byte stream (.raw): 1-24 garbage bytes before ~1% of the frames
              (without 0xFD/0xFE: no false start of a frame), ~0.05% of the frames cut short (the kept head
              holds no second start byte; the frames it swallows then fail their CRC, checked here)

The truth (JSON beside each capture) says what a reader must find: `frames` complete frames (the
corrupted-CRC ones included, `bad_crc` of them), `truncated` frames cut short (not frames), `signed`,
`v1`, `records`. Pcaps go through scripts/capgen's `write_pcap`, tlogs its `write_tlog`; the TCP
segments are tcp_bench.py's `_packet`, the UDP headers checksummed with bench_capture.py's `_ip_checksum`.
"""

from __future__ import annotations

import json
import random
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent)]
from bench_capture import _TIME_FIELDS, GCS, MIX, VEHICLE, _ip_checksum, _pools  # noqa: E402
from tcp_bench import _packet  # noqa: E402

from scripts.capgen.constants import (  # noqa: E402
    ARDUPILOT_TCP_PORT,
    BASE_TIME_US,
    GCS_TCP_PORT,
    LINKTYPE_ETHERNET,
    SIGNING_KEY,
)

GEN_VERSION = 5  # bump when a generated capture changes
KINDS = ("clean", "mixsign", "signedv1", "badcrc", "tcp", "tlog", "raw")
SIGNED_KINDS = ("mixsign", "signedv1")
SUFFIX = {"tlog": ".tlog", "raw": ".raw"}  # the others: .pcap
SEEDS = {k: 36_000 + i for i, k in enumerate(KINDS)}
MIXSIGN_SHARE, BAD_CRC_SHARE, NOISE_SHARE, CUT_SHARE = 0.25, 0.03, 0.01, 0.0005
KEY = SIGNING_KEY  # capgen's fixed 32-byte key (SHA-256 of its passphrase), as `--key hex:` gives it

Sends = list[tuple[int, str, list[Any]]]  # (µs since the capture start, "V" or "G", capgen Frames)


def telemetry(frames: int, rng: random.Random, *, sign: float = 0.0, gcs_v1: bool = False) -> Sends:
    """`frames` frames as the sends (datagrams, stream writes) of the vehicle ("V") and the GCS ("G")."""
    from pymavlink.dialects.v10 import all as m1
    from pymavlink.dialects.v20 import all as m2

    from scripts.capgen.frames import Endpoint

    pools = _pools(m2, rng)
    names, senders, weights = zip(*MIX)
    cum = [sum(weights[:i + 1]) for i in range(len(weights))]
    vehicle = [k for k, s in enumerate(senders) if s == "V"]
    eps = {"V": Endpoint(m2, VEHICLE[3], VEHICLE[4], link_id=0 if sign else None),
           "G": Endpoint(m1 if gcs_v1 else m2, GCS[3], GCS[4])}
    vsign = eps["V"].mav.signing
    out: Sends = []
    t, n = 0, 0
    while n < frames:
        k = rng.choices(range(len(MIX)), cum_weights=cum)[0]
        who = senders[k]
        count = rng.choice((2, 2, 3)) if who == "V" and rng.random() < 0.10 else 1
        sent = []
        for j in range(min(count, frames - n)):
            if j:
                k = rng.choice(vehicle)
            msg = rng.choice(pools[names[k]])
            tb = t // 1000 + 12_345  # the vehicle's time since boot, ms
            for fld in _TIME_FIELDS:
                if hasattr(msg, fld):
                    setattr(msg, fld, tb * 1000 if fld != "time_boot_ms" else tb & 0xFFFFFFFF)
            if who == "G" and gcs_v1:  # the same values in the v1 message (no extension fields)
                cls = getattr(m1, type(msg).__name__)
                msg = cls(*[getattr(msg, f) for f in cls.fieldnames])
            if who == "V" and sign:
                vsign.sign_outgoing = sign >= 1.0 or rng.random() < sign
            sent.append(eps[who].pack(msg, BASE_TIME_US + t))
        n += len(sent)
        out.append((t, who, sent))
        t += 1 + int(rng.expovariate(1 / 1000))  # ~1,000 frames/s
    return out


def _truth(kind: str, sends: Sends, records: int, **extra: int) -> dict[str, Any]:
    fr = [f for _, _, fs in sends for f in fs]
    return {"kind": kind, "frames": len(fr), "signed": sum(f.signed for f in fr),
            "v1": sum(f.version == 1 for f in fr), "bad_crc": 0, "truncated": 0, "records": records, **extra}


def _ends(who: str) -> tuple[tuple, tuple]:
    return (VEHICLE, GCS) if who == "V" else (GCS, VEHICLE)


def _udp_pcap(path: Path, sends: Sends, data: Callable[[Any], bytes] = lambda f: f.data) -> int:
    from scripts.capgen.packets import Pkt
    from scripts.capgen.writers import write_pcap

    ip, pkts = struct.Struct("!BBHHHBBH4s4s"), []
    for i, (t, who, frames) in enumerate(sends):
        src, dst = _ends(who)
        payload = b"".join(data(f) for f in frames)
        ulen = 8 + len(payload)
        iph = ip.pack(0x45, 0, 20 + ulen, i & 0xFFFF, 0x4000, 64, 17, 0, src[1], dst[1])
        iph = iph[:10] + struct.pack("!H", _ip_checksum(iph)) + iph[12:]
        pkts.append(Pkt(t * 1000, dst[0] + src[0] + b"\x08\x00" + iph
                        + struct.pack("!HHHH", src[2], dst[2], ulen, 0) + payload))
    write_pcap(path, LINKTYPE_ETHERNET, pkts)
    return len(pkts)


def _corrupt(sends: Sends, rng: random.Random) -> tuple[dict[int, bytes], int]:
    """3% of the frames with their last CRC byte damaged: {id(frame): damaged bytes}, and how many."""
    bad: dict[int, bytes] = {}
    for _, _, frames in sends:
        prev = False  # never two damaged frames in a row in one datagram (see the module's docstring)
        for f in frames:
            prev = rng.random() < BAD_CRC_SHARE and not prev
            if prev:
                d = bytearray(f.data)
                d[-1] ^= rng.randint(1, 255)  # unsigned v2: the last byte is the CRC's high byte
                bad[id(f)] = bytes(d)
    return bad, len(bad)


def _seg_size(rng: random.Random) -> int:
    """A TCP segment's payload size: mostly 48-600 bytes (several frames, cut anywhere), 1 in 10 tiny."""
    return rng.randint(5, 24) if rng.random() < 0.1 else rng.randint(48, 600)


def _tcp_pcap(path: Path, sends: Sends, rng: random.Random) -> int:
    from scripts.capgen.packets import Pkt
    from scripts.capgen.writers import write_pcap

    port = {"V": ARDUPILOT_TCP_PORT, "G": GCS_TCP_PORT}
    nxt = {"V": 1_000_000, "G": 3_000_000}  # each side's next sequence number (from its ISN)
    other = {"V": "G", "G": "V"}
    ipid = {"V": 100, "G": 5_000}
    pkts: list[Any] = []
    last = [0]  # the last record's time: records go out in time order

    def seg(t: int, who: str, flags: int, data: bytes = b"") -> None:
        src, dst = _ends(who)
        ipid[who] = (ipid[who] + 1) & 0xFFFF
        last[0] = t = max(t, last[0])
        ack = nxt[other[who]] if flags & 0x10 else 0  # no ACK flag (the first SYN): no ACK number
        pkts.append(Pkt(t * 1000, _packet(dst[0] + src[0] + b"\x08\x00", src[1], dst[1], port[who],
                                          port[other[who]], nxt[who], ack, flags, data, ipid[who])))
        nxt[who] += len(data) + (1 if flags & 0x03 else 0)  # SYN and FIN take a sequence number

    seg(0, "G", 0x02)
    seg(40, "V", 0x12)
    seg(80, "G", 0x10)
    buf = {"V": bytearray(), "G": bytearray()}
    since = {"V": 0, "G": 0}  # when the oldest buffered byte was written
    unacked = {"V": 0, "G": 0}  # data segments a side received since it last acknowledged
    size = {w: _seg_size(rng) for w in buf}

    def flush(t: int, who: str, upto: int) -> None:
        seg(t, who, 0x18, bytes(buf[who][:upto]))
        del buf[who][:upto]
        unacked[who] = 0
        unacked[other[who]] += 1
        if unacked[other[who]] >= 2:  # the receiver's delayed ACK
            seg(t + 30, other[who], 0x10)
            unacked[other[who]] = 0

    for t, who, frames in sends:
        t += 200
        for w in buf:
            if buf[w] and t - since[w] > 20_000:  # a leftover goes out after 20 ms
                flush(since[w] + 20_000, w, len(buf[w]))
        if not buf[who]:
            since[who] = t
        buf[who] += b"".join(f.data for f in frames)
        while len(buf[who]) >= size[who]:
            flush(t, who, size[who])
            since[who] = t
            size[who] = _seg_size(rng)
    t = sends[-1][0] + 1_000
    for w in buf:
        if buf[w]:
            flush(t, w, len(buf[w]))
    seg(t + 100, "G", 0x11)
    seg(t + 140, "V", 0x11)
    seg(t + 180, "G", 0x10)
    write_pcap(path, LINKTYPE_ETHERNET, pkts)
    return len(pkts)


def _glued_crc_ok(glued: bytes) -> bool:
    """Whether a reader taking a cut frame's head and the bytes after it as one frame sees a good CRC (never,
    when those bytes end before that frame's CRC would)."""
    from scripts.capgen.frames import frame_crc_ok

    size = (8 if glued[0] == 0xFE else 12) + glued[1]
    return len(glued) >= size and frame_crc_ok(glued)


def _ends_on_a_frame(f: bytes, keep: int, after: list[bytes]) -> bool:
    """Whether the cut frame's LEN, counted over the frames after it, ends where one of them ends: then the
    framer (and MAVLink's C parser, which reads LEN bytes on) takes head and frames as one bad-CRC frame and
    the frames inside it are read by no receiver, which this capture's truth does not count."""
    size = (8 if f[0] == 0xFE else 12) + f[1]
    at = keep
    for g in after:
        at += len(g)
        if at == size:
            return True
        if at > size:
            return False
    return False


def _raw(path: Path, sends: Sends, rng: random.Random) -> tuple[int, int, int]:
    """The byte stream with line noise; (frames kept whole, noise bursts, frames cut short)."""
    from scripts.capgen.frames import assert_no_stx

    frames = [f.data for _, _, fs in sends for f in fs]
    out, whole, noise, cut = bytearray(), 0, 0, 0
    clean = bytes(b for b in range(256) if b not in (0xFD, 0xFE))
    quiet = 0  # no noise in the two frames after a cut: the glued bytes checked below are what is written
    for i, f in enumerate(frames):
        noisy = rng.random() < NOISE_SHARE and not quiet
        if noisy:
            junk = bytes(rng.choice(clean) for _ in range(rng.randint(1, 24)))
            assert_no_stx(junk, "line noise")
            out += junk
            noise += 1
        keep = rng.randint(10, len(f) - 1)  # its header whole (v2), some of the rest
        quiet = max(quiet - 1, 0)
        # (no cut right after noise: the framer reports noise and a cut head together as skipped bytes)
        cut_here = (rng.random() < CUT_SHARE and not quiet and not noisy and i + 2 < len(frames)
                     and b"\xfd" not in f[1:keep] and b"\xfe" not in f[1:keep]
                     and not _glued_crc_ok(f[:keep] + frames[i + 1] + frames[i + 2])
                     and not _ends_on_a_frame(f, keep, frames[i + 1:i + 4]))
        # a frame cut short: its head holds no second start byte, and a reader that took the next frames'
        # bytes as its tail sees a bad CRC
        if cut_here:
            out += f[:keep]
            cut += 1
            quiet = 2
        else:
            out += f
            whole += 1
    path.write_bytes(bytes(out))
    return whole, noise, cut


def generate(kind: str, path: Path, frames: int) -> dict[str, Any]:
    """Write the capture of `kind` to `path`; return its truth."""
    from scripts.capgen.writers import write_tlog

    rng = random.Random(SEEDS[kind])
    sends = telemetry(frames, rng, sign={"mixsign": MIXSIGN_SHARE, "signedv1": 1.0}.get(kind, 0.0),
                      gcs_v1=kind == "signedv1")
    if kind in ("clean", "mixsign", "signedv1"):
        return _truth(kind, sends, _udp_pcap(path, sends))
    if kind == "badcrc":
        bad, nbad = _corrupt(sends, rng)
        truth = _truth(kind, sends, _udp_pcap(path, sends, lambda f: bad.get(id(f), f.data)))
        truth["bad_crc"] = nbad
        return truth
    if kind == "tcp":
        return _truth(kind, sends, _tcp_pcap(path, sends, rng))
    if kind == "tlog":
        recs = [(t, f.data) for t, _, fs in sends for f in fs]
        write_tlog(path, recs)
        return _truth(kind, sends, len(recs))
    whole, noise, cut = _raw(path, sends, rng)
    truth = _truth(kind, sends, 0, noise_bursts=noise)
    truth.update(frames=whole, truncated=cut)
    return truth


def capture(kind: str, out_dir: Path, frames: int) -> tuple[Path, dict[str, Any]]:
    """The capture of `kind` with `frames` frames, generated once into `out_dir`, and its truth."""
    path = out_dir / f"kind_{kind}_{frames}_v{GEN_VERSION}{SUFFIX.get(kind, '.pcap')}"
    meta = path.with_name(path.name + ".json")
    if path.is_file() and meta.is_file():
        return path, json.loads(meta.read_text())
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    tmp = path.with_name(path.name + ".tmp")
    truth = generate(kind, tmp, frames)
    tmp.replace(path)
    truth["generate_s"] = round(time.perf_counter() - t0, 1)
    meta.write_text(json.dumps(truth, indent=1))
    return path, truth
