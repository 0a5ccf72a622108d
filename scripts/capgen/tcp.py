"""The TCP session: one connection whose byte streams are cut into segments at arbitrary points, with
pure ACKs, a spurious retransmission and an out-of-order pair, so that reassembly has real work to do;
expected.json says in which record each frame completes."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from random import Random
from typing import Any

import pymavlink.dialects.v20.common as mav2
from scapy.layers.inet import IP, TCP
from scapy.layers.l2 import Ether

from .constants import (
    ARDUPILOT_TCP_PORT,
    GCS_TCP_PORT,
    LINKTYPE_ETHERNET,
    LOOPBACK_V4,
    MAV_AUTOPILOT_PX4,
    SYN_WINDOW,
    ZERO_MAC,
)
from .frames import Frame, Send
from .packets import Pkt, wrap_packet
from .story import SHORT_STORY
from .summary import summarize
from .telemetry import PX4_STREAMS, Profile, build_session
from .writers import write_pcap


@dataclass
class Segment:
    """One TCP segment before it becomes a packet. `rel_seq` counts from the ISN (data starts at 1)."""

    t_us: int
    side: str
    flags: str
    rel_seq: int | None  # None: the sender's next sequence number at that moment (pure ACKs)
    payload: bytes = b""
    # Frames completing in this segment: (segment holding the STX, offset of the STX there, frame).
    frames: list[tuple[Segment, int, Frame]] = field(default_factory=list)
    options: list[tuple[str, Any]] = field(default_factory=list)


def segment_stream(sends: Iterable[Send], side: str, rng: Random, end_us: int) -> tuple[list[Segment], set[int]]:
    """Cut one side's byte stream into segments at arbitrary points: several frames per segment, some
    frames across two or three segments. Leftovers are flushed at random, always after a transaction
    reply, and always by the GCS (its writes are rare). Also returns how many segments frames span."""
    segs: list[Segment] = []
    buf, sent = b"", 1
    pending: list[list[Any]] = []  # [start in buf, end in buf, frame, segments touched, STX segment]
    spans: set[int] = set()

    def emit(n: int, t_us: int) -> None:
        nonlocal buf, pending, sent
        seg = Segment(t_us, side, "PA", sent, buf[:n])
        for p in pending:
            p[3] += p[0] < n
            if 0 <= p[0] < n:
                p[4] = seg
            if p[1] <= n:
                seg.frames.append((p[4], p[0] + seg.rel_seq - p[4].rel_seq, p[2]))
                spans.add(p[3])
        pending = [[a - n, b - n, f, k, first] for a, b, f, k, first in pending if b > n]
        buf, sent = buf[n:], sent + n
        segs.append(seg)

    for send in sends:
        for fr in send.frames:
            pending.append([len(buf), len(buf) + len(fr.data), fr, 0, None])
            buf += fr.data
        t = send.t_us
        while True:
            size = rng.randint(5, 24) if rng.random() < 0.1 else rng.randint(48, 300)
            if len(buf) < size:
                break
            emit(size, t)
            t += rng.randint(8, 40)
        if buf and (send.urgent or side == "gcs" or rng.random() < 0.4):
            emit(len(buf), t)
    if buf:
        emit(len(buf), end_us)
    return segs, spans


def px4_sitl_tcp(outdir: Path) -> dict[str, Any]:
    """The SHORT_STORY session over one TCP connection from the GCS to the vehicle at 127.0.0.1:5760."""
    rng = Random(2)
    sends = build_session(Profile(mav2, MAV_AUTOPILOT_PX4, PX4_STREAMS), SHORT_STORY, rng)
    port = {"vehicle": ARDUPILOT_TCP_PORT, "gcs": GCS_TCP_PORT}
    peer = {"vehicle": "gcs", "gcs": "vehicle"}
    isn = {"vehicle": rng.getrandbits(32), "gcs": rng.getrandbits(32)}
    end_us = round(SHORT_STORY.duration * 1e6)

    syn_opts = [("MSS", 65_495), ("SAckOK", b""), ("NOP", None), ("WScale", 7)]
    handshake = [Segment(0, "gcs", "S", 0, options=syn_opts), Segment(45, "vehicle", "SA", 0, options=syn_opts),
                 Segment(80, "gcs", "A", 1)]
    vehicle_segs, vehicle_spans = segment_stream((s for s in sends if s.side == "vehicle"), "vehicle", rng, end_us)
    gcs_segs, gcs_spans = segment_stream((s for s in sends if s.side == "gcs"), "gcs", rng, end_us)
    if not {2, 3} <= vehicle_spans | gcs_spans:
        raise AssertionError("the TCP capture must hold frames split across 2 and across 3 segments")
    data = sorted(vehicle_segs + gcs_segs, key=lambda s: s.t_us)

    # Delayed ACKs: every second data segment from the vehicle, every one from the GCS.
    segs, unacked = list(handshake), 0
    for s in data:
        segs.append(s)
        unacked = unacked + 1 if s.side == "vehicle" else 2
        if unacked >= 2:
            segs.append(Segment(s.t_us + rng.randint(20, 60), peer[s.side], "A", None))
            unacked = 0
    segs.sort(key=lambda s: s.t_us)

    # One spurious retransmission (an exact copy, 210 ms later: the minimum RTO) ...
    orig = next(s for s in segs if s.side == "vehicle" and s.payload and s.t_us >= 6_000_000)
    retransmission = Segment(orig.t_us + 210_000, "vehicle", "PA", orig.rel_seq, orig.payload)
    segs.append(retransmission)
    segs.sort(key=lambda s: s.t_us)
    # ... and one pair of adjacent vehicle segments recorded in the wrong order.
    a = next(i for i, s in enumerate(segs) if s.t_us >= 11_000_000 and all(
        x.side == "vehicle" and x.frames for x in segs[i:i + 2]))
    segs[a], segs[a + 1] = segs[a + 1], segs[a]
    swapped = segs[a:a + 2]
    segs[a].t_us, segs[a + 1].t_us = segs[a + 1].t_us, segs[a].t_us

    # Close: the GCS sends FIN, the vehicle acknowledges it and closes too.
    nxt = {side: max(s.rel_seq + len(s.payload) for s in data if s.side == side) for side in peer}
    end = end_us + 150_000
    segs += [Segment(end, "gcs", "FA", nxt["gcs"]), Segment(end + 40, "vehicle", "A", nxt["vehicle"]),
             Segment(end + 300, "vehicle", "FA", nxt["vehicle"]), Segment(end + 340, "gcs", "A", nxt["gcs"] + 1)]

    # Sequence and acknowledgement numbers: on loopback whatever was sent before has arrived.
    sent_to = {"vehicle": 1, "gcs": 1}  # relative sequence number after the last byte (or SYN/FIN) sent
    ip_id = {side: rng.randint(1_000, 60_000) for side in peer}
    last_ack = {"vehicle": -1, "gcs": -1}
    pkts: list[Pkt] = []
    record_of: dict[int, int] = {}  # id(segment) -> record number
    for s in segs:
        other = peer[s.side]
        rel_seq = sent_to[s.side] if s.rel_seq is None else s.rel_seq
        sent_to[s.side] = max(sent_to[s.side], rel_seq + len(s.payload) + ("F" in s.flags))
        ack = (isn[other] + sent_to[other]) % 2**32 if "A" in s.flags else 0
        if s.rel_seq is None and ack == last_ack[s.side]:
            continue  # a reply already acknowledged this: no duplicate ACK
        last_ack[s.side] = ack
        ip_id[s.side] = (ip_id[s.side] + 1) % 65_536
        tcp = TCP(sport=port[s.side], dport=port[other], seq=(isn[s.side] + rel_seq) % 2**32, ack=ack,
                  flags=s.flags, window=SYN_WINDOW.get(s.flags, 512), options=s.options)
        ip = IP(src=LOOPBACK_V4, dst=LOOPBACK_V4, id=ip_id[s.side], flags="DF", ttl=64)
        pkts.append(wrap_packet(Ether(src=ZERO_MAC, dst=ZERO_MAC) / ip / tcp, s.payload, s.t_us))
        record_of.setdefault(id(s), len(pkts))
    offsets = write_pcap(outdir / "px4_sitl_tcp.pcap", LINKTYPE_ETHERNET, pkts)

    # A frame completes in the record that makes the stream contiguous up to its last byte: for the
    # out-of-order pair, the later record (as Wireshark shows a reassembled PDU).
    completed: dict[int, list[tuple[int | None, Frame]]] = {}
    for side_segs in (vehicle_segs, gcs_segs):
        latest = 0
        for s in side_segs:  # in stream order
            latest = max(latest, record_of[id(s)])
            for first, off, fr in s.frames:
                rec = record_of[id(first)]
                completed.setdefault(latest, []).append((offsets[rec - 1] + pkts[rec - 1].payload_at + off, fr))
    located = [(rec, idx, off, fr) for rec in sorted(completed)
               for idx, (off, fr) in enumerate(completed[rec], start=1)]
    summary = summarize("pcap", [LINKTYPE_ETHERNET], len(pkts), located, [], 0)
    summary["events"] = {"retransmission": [record_of[id(orig)], record_of[id(retransmission)]],
                         "out_of_order": [record_of[id(x)] for x in swapped]}
    return summary
