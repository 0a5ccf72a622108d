"""Frame numbers stay unique however long a TCP hole lives (mavscope.pipeline.dissect: _later, _hold).

A frame is numbered `record.index` by the record that completed it; after a TCP hole, reassembly can give out
bytes records later, dated by an earlier record, and a hole or the stream's end can cut a frame begun in an
earlier record: those frames are numbered after the frames that record gave when it was read. mavscope kept
the last index of the latest 65,536 records and forgot the oldest, so a hole that outlived 65,536 records
with frames numbered a frame `N.1` a second time. The expected numbers come from the construction: which
frames each record's bytes complete, in order (pymavlink packs every frame; the stream's bytes are cut by
hand), and that no two frames may share a number.
"""

from __future__ import annotations

from pathlib import Path

from scapy.layers.inet import IP, TCP
from scapy.layers.l2 import Ether

from mavscope.capture.synth import udp_packet
from tests.support import tcpflows as tf
from tests.support.builders import write_pcap

FLOOD = 66_000  # UDP records with a frame each while the hole lives (more than the 65,536 once kept)
PURE, NATIVE = {"MAVSCOPE_PURE": "1"}, {"MAVSCOPE_PURE": ""}


def tcp(src: tuple[str, int], dst: tuple[str, int], seq: int, flags: str, data: bytes = b"", ack: int = 0) -> bytes:
    p = Ether(src="02:00:00:00:00:01", dst="02:00:00:00:00:02") / IP(src=src[0], dst=dst[0]) / TCP(
        sport=src[1], dport=dst[1], seq=seq % (1 << 32), ack=ack % (1 << 32), flags=flags) / data
    return bytes(p)


def capture(path: Path) -> tuple[Path, dict[tuple[int, int], str]]:
    """The capture, and the frames the construction says each record completes: (record, index) -> what.

    Stream A (10.0.0.1:5760, picked up mid-way) sends HEARTBEATs a0..a5: record 1 holds a0, a1 and the first
    10 bytes of a2; a4 is never captured; record 2 holds a5 (beyond the hole); record 3 the rest of a2 and a3
    (which fills the hole up to a4). Stream B (10.0.0.3:5760) sends b0 and the first 10 bytes of b1 in record
    4. Then FLOOD UDP HEARTBEATs, one a record, all at the same time (the hole's 2 s never pass). Then the
    ground station acknowledges A past a5 (a4's hole given up, a5 read) and B ends (FIN: b1 cut short)."""
    a, b = tf.heartbeats(6), tf.heartbeats(2)
    starts = [sum(map(len, a[:i])) for i in range(7)]
    gcs = ("10.0.0.2", 40000)
    va, vb = ("10.0.0.1", 5760), ("10.0.0.3", 5760)
    isn_a, isn_b = 1000, 7000
    packets = [
        tcp(va, gcs, isn_a, "PA", a[0] + a[1] + a[2][:10]),
        tcp(va, gcs, isn_a + starts[5], "PA", a[5]),
        tcp(va, gcs, isn_a + starts[2] + 10, "PA", a[2][10:] + a[3]),
        tcp(vb, gcs, isn_b, "PA", b[0] + b[1][:10]),
    ]
    hb = tf.heartbeats(1)[0]
    packets += [udp_packet("192.168.1.2", 40000, f"192.168.{i // 250 % 250}.{i % 250 + 1}", 14550, hb)
                for i in range(FLOOD)]
    ack, fin = len(packets) + 1, len(packets) + 2
    packets += [tcp(gcs, va, 5000, "A", ack=isn_a + starts[6]), tcp(vb, gcs, isn_b + len(b[0]) + 10, "FA")]
    write_pcap(path, [(1.0, p) for p in packets])
    expected = {(1, 1): "a0", (1, 2): "a1", (3, 1): "a2", (3, 2): "a3", (4, 1): "b0"}
    expected |= {(5 + i, 1): "udp" for i in range(FLOOD)}
    # a5, given out when the ACK gives a4's hole up, is dated by an earlier record (its own or the one that
    # filled the hole before it: 2 or 3), numbered after that record's frames; b1's first 10 bytes, cut by
    # the FIN, are record 4's, after b0
    assert (ack, fin) == (5 + FLOOD, 6 + FLOOD)
    return path, expected


def test_frame_numbers_are_unique_past_a_long_hole(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    path, expected = capture(tmp_path / "hole.pcap")
    rows = cli.jsonl(path, environ=PURE)
    numbers = [(r["frame"], r["index"]) for r in rows]
    assert len(numbers) == len(set(numbers)), "a frame number given twice"
    got = set(numbers)
    assert set(expected) <= got
    rest = sorted(got - set(expected))
    # the two frames dated by earlier records: a5 after record 2's none (2.1) or record 3's two (3.3), and b1's
    # cut frame after b0 (4.2)
    assert rest in ([(2, 1), (4, 2)], [(3, 3), (4, 2)]), rest
    assert cli.jsonl(path, environ=NATIVE) == rows


def test_frame_numbers_are_unique_with_many_holes(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    # 300 HEARTBEATs cut into 7-byte segments (frames begun in one record, cut by the next hole), every 5th
    # segment missed, each pair of segments swapped (bytes held beyond a hole), with and without the ground
    # station's ACKs, all at one time or a second apart: whichever way each hole is given up, no two frames
    # share a number
    segs = tf.chunks(tf.heartbeats(300), 7, period=0.0)
    order = [i ^ 1 for i in range(len(segs)) if i ^ 1 < len(segs)]
    for acks in (True, False):
        for n, seg in enumerate((segs, tf.chunks(tf.heartbeats(300), 7, period=1.0))):
            cap = tf.build(seg, missed=set(range(3, len(seg), 5)), order=order, acks=acks, fin=n == 0)
            rows = cli.jsonl(cap.write(tmp_path / f"holes{acks}{n}.pcap"), environ=PURE)
            numbers = [(r["frame"], r["index"]) for r in rows]
            assert rows and len(numbers) == len(set(numbers)), (acks, n)
            # every frame is dated by one of the stream's captured data segments (the construction's records)
            assert {r["frame"] for r in rows} <= set(cap.record_of.values()), (acks, n)
            assert cli.jsonl(tmp_path / f"holes{acks}{n}.pcap", environ=NATIVE) == rows
