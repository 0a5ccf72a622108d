"""TCP reassembly against hostile input: injected SYNs (defect 8) and memory bounds (defect 7).

An injected SYN with a new sequence number used to restart an established stream, so the rest of it was
dropped as "retransmission already delivered" (18 of 30 frames hidden). A real endpoint ignores such a
SYN (RFC 5961); now every frame is shown and the SYN is noted. A new connection reusing the 4-tuple after
a FIN, an RST or a long idle time still starts a new stream, without a note.

Memory used to be bounded per direction only: a million streams, a million SYN generations or hundreds
of streams buffering out-of-order bytes grew without limit. The bounds are checked on the reassembler's
own accounting and with tracemalloc (never with wall-clock time).
"""

from __future__ import annotations

import struct
import tracemalloc
from pathlib import Path

import pytest
from scapy.utils import checksum

from mavscope.capture.detect import open_capture
from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.notes import CODES, Severity
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.transport.tcp import TCP_FIN, TCP_RST, TCP_SYN, TcpReassembler
from tests.support import builders
from tests.support.pmav import command_long_rtl, heartbeat, mav2

CLIENT, SERVER = b"\x0a\x00\x00\x01", b"\x0a\x00\x00\x02"
TCP_ACK = 0x10
PSH_ACK = 0x18


def tcp_packet(src: bytes, dst: bytes, sport: int, dport: int, seq: int, flags: int, data: bytes) -> bytes:
    """An Ethernet/IPv4/TCP packet, its TCP checksum right (scapy's Internet checksum over the pseudo-header)."""
    tcp = struct.pack("!HHIIBBHHH", sport, dport, seq % (1 << 32), 0, 5 << 4, flags, 65535, 0, 0)
    pseudo = src + dst + struct.pack("!BBH", 0, 6, len(tcp) + len(data))
    tcp = tcp[:16] + struct.pack("!H", checksum(pseudo + tcp + data)) + tcp[18:]
    ip = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 40 + len(data), 0, 0x4000, 64, 6, 0, src, dst)
    return b"\x02\0\0\0\0\x02\x02\0\0\0\0\x01\x08\x00" + ip + tcp + data


def dissect(path: Path, dialect) -> tuple[list[Frame], list[str]]:  # type: ignore[no-untyped-def]
    """The frames of a capture and the note codes of frames and anomalies."""
    with open_capture(path) as reader:
        items = list(Dissector(dialect).run(reader))
    frames = [i for i in items if isinstance(i, Frame)]
    codes = [n.code for i in items for n in i.notes]
    assert all(isinstance(i, (Frame, Anomaly)) for i in items)
    return frames, codes


def frames_30() -> list[bytes]:
    mav = mav2(1, 1)
    return [heartbeat(mav) for _ in range(30)]


def stream_with_syn(isn_injected: int, syn_data: bytes = b"", at: int = 12) -> list[bytes]:
    """A handshake, then 30 frames client -> server, one per segment, and a SYN injected after frame `at`."""
    packets = [tcp_packet(CLIENT, SERVER, 40000, 5760, 1000, TCP_SYN, b"")]
    seq = 1001
    for i, f in enumerate(frames_30()):
        packets.append(tcp_packet(CLIENT, SERVER, 40000, 5760, seq, PSH_ACK, f))
        seq += len(f)
        if i == at:
            packets.append(tcp_packet(CLIENT, SERVER, 40000, 5760, isn_injected, TCP_SYN, syn_data))
    return packets


def test_the_note_code_is_registered() -> None:
    assert CODES["tcp-suspicious-syn"].severity is Severity.WARN


@pytest.mark.parametrize("isn", [500_000, 1001 + 13 * 21 + 5, 3_000_000_000, 0, 1001 + 13 * 21 - 1, 1000])
def test_an_injected_syn_hides_no_frame(tmp_path: Path, dialect, isn: int) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "syn.pcap"
    builders.write_pcap(path, builders.timed(stream_with_syn(isn), 1_700_000_000))  # a second apart
    frames, codes = dissect(path, dialect)
    assert [f.raw for f in frames] == frames_30() and all(f.crc_status is CrcStatus.OK for f in frames)
    assert len({f.src for f in frames}) == 1
    if isn == 1000:  # the stream's own SYN again: a retransmission, nothing to note
        assert codes == []
    else:
        assert codes == ["tcp-suspicious-syn"]
        suspicious = [n for f in frames for n in f.notes]
        assert suspicious and "RFC 5961" in suspicious[0].message and str(isn) in suspicious[0].message


def test_an_injected_syn_with_a_frame_shows_both_streams(tmp_path: Path, dialect) -> None:  # type: ignore[no-untyped-def]
    forged = command_long_rtl(mav2(255, 190))
    path = tmp_path / "syn_data.pcap"
    builders.write_pcap(path, builders.timed(stream_with_syn(77_777_777, forged), 1_700_000_000))
    frames, codes = dissect(path, dialect)
    assert [f.raw for f in frames if f.raw != forged] == frames_30()
    injected = [f for f in frames if f.raw == forged]
    assert len(injected) == 1 and [n.code for n in injected[0].notes] == ["tcp-suspicious-syn"]
    assert codes == ["tcp-suspicious-syn"]


@pytest.mark.parametrize("end", [TCP_FIN, TCP_RST, "idle"])
def test_a_new_connection_on_the_same_4_tuple_is_a_new_stream(end: object) -> None:
    r = TcpReassembler(idle_records=100)
    a, b = "10.0.0.1:40000", "10.0.0.2:5760"
    first = r.segment(a, b, 100, TCP_SYN, b"", 1, 0) + r.segment(a, b, 101, PSH_ACK, b"old", 2, 0)
    r.segment(b, a, 5000, TCP_SYN | TCP_ACK, b"", 3, 0)
    record = 4
    if end == "idle":
        record = 500
    else:
        r.segment(a, b, 104, end | TCP_ACK, b"", 4, 0)  # type: ignore[operator]
        if end == TCP_FIN:
            r.segment(b, a, 5001, TCP_FIN | TCP_ACK, b"", 5, 0)
        assert ("tcp", a, b, 0) in r.pop_ended()
    second = r.segment(a, b, 900_000, TCP_SYN, b"", record + 1, 0)
    second += r.segment(b, a, 70_000, TCP_SYN | TCP_ACK, b"", record + 2, 0)
    second += r.segment(a, b, 900_001, PSH_ACK, b"new", record + 3, 0)
    assert [p.data for p in first] == [b"old"] and [p.data for p in second] == [b"new"]
    assert first[0].stream != second[0].stream
    assert not [n for p in first + second + r.flush() for n in p.notes]


def test_syn_ack_answering_a_new_syn_is_not_noted_twice() -> None:
    """The FIN of the first connection was not captured: the new SYN is noted once (not its SYN-ACK), and
    both connections' bytes reach their own streams."""
    r = TcpReassembler()
    a, b = "10.0.0.1:40000", "10.0.0.2:5760"
    out = r.segment(a, b, 100, TCP_SYN, b"", 1, 0) + r.segment(b, a, 5000, TCP_SYN | TCP_ACK, b"", 2, 0)
    out += r.segment(a, b, 101, PSH_ACK, b"old-a", 3, 0) + r.segment(b, a, 5001, PSH_ACK, b"old-b", 4, 0)
    out += r.segment(a, b, 900_000, TCP_SYN, b"", 5, 0) + r.segment(b, a, 70_000, TCP_SYN | TCP_ACK, b"", 6, 0)
    out += r.segment(a, b, 900_001, PSH_ACK, b"new-a", 7, 0) + r.segment(b, a, 70_001, PSH_ACK, b"new-b", 8, 0)
    out += r.segment(a, b, 106, PSH_ACK, b"late-a", 9, 0)  # the old connection is still there
    streams: dict[object, bytes] = {}
    for p in out:
        streams[p.stream] = streams.get(p.stream, b"") + p.data
    assert sorted(streams.values()) == [b"new-a", b"new-b", b"old-alate-a", b"old-b"]
    assert [n.code for p in out for n in p.notes] == ["tcp-suspicious-syn"]


def test_many_injected_syns_keep_the_established_stream() -> None:
    r = TcpReassembler()
    a, b = "10.0.0.1:40000", "10.0.0.2:5760"
    out = r.segment(a, b, 100, TCP_SYN, b"", 1, 0)
    seq = 101
    for i in range(2000):
        out += r.segment(a, b, seq, PSH_ACK, b"%04d" % i, 2 + 2 * i, 0)
        seq += 4
        out += r.segment(a, b, (i * 2_654_435_761) % (1 << 32), TCP_SYN, b"x" if i % 2 else b"", 3 + 2 * i, 0)
    legit = b"".join(p.data for p in out if p.stream == ("tcp", a, b, 0))
    assert legit == b"".join(b"%04d" % i for i in range(2000))
    assert r.tracked() <= 2
    assert sum(n.code == "tcp-suspicious-syn" for p in out + r.flush() for n in p.notes) == 2000


# ---- memory bounds (defect 7) ---------------------------------------------------------------------------


def test_buffered_bytes_are_bounded_over_all_directions() -> None:
    r = TcpReassembler(max_buffered=1 << 20, max_total=1 << 16)
    delivered = 0
    sent = 0
    for k in range(1000):  # 300 streams each buffering 1 MB was held whole; here 1000 streams, 10 KB each
        src = f"10.1.{k // 256}.{k % 256}:40000"
        delivered += sum(len(p.data) for p in r.segment(src, "10.0.0.2:5760", 0, PSH_ACK, b"a", 1, 0))
        sent += 1
        for j in range(10):
            data = bytes(1000)
            delivered += sum(len(p.data) for p in r.segment(src, "10.0.0.2:5760", 100 + 1000 * j, PSH_ACK, data,
                                                            2, 0))
            sent += len(data)
            assert r.total <= (1 << 16)
    out = r.flush()
    delivered += sum(len(p.data) for p in out)
    assert delivered == sent  # nothing vanishes: the bytes go out after a tcp-gap note


def test_one_byte_segments_are_charged_their_overhead() -> None:
    r = TcpReassembler(max_buffered=1 << 20, max_total=1 << 16)
    r.segment("a:1", "b:2", 0, PSH_ACK, b"a", 1, 0)
    for i in range(10_000):  # out of order, one byte each
        r.segment("a:1", "b:2", 10 + 2 * i, PSH_ACK, b"x", 2 + i, 0)
        assert r.total <= 1 << 16
    assert r.buffered_segments() <= (1 << 16) // 200


def test_directions_are_bounded_and_the_flood_is_noted_sparingly() -> None:
    r = TcpReassembler(max_directions=100)
    out = []
    for k in range(10_000):
        out += r.segment(f"10.2.{k // 256}.{k % 256}:40000", "10.0.0.2:5760", 7 * k, PSH_ACK, b"data", k + 1, 0)
        assert r.tracked() <= 100
    given_up = [n for p in out for n in p.notes if n.code == "tcp-gap"]
    assert 5 <= len(given_up) <= 15 and "given up" in given_up[-1].message  # 1st, 2nd, 4th... of 9900
    assert len(r.pop_ended()) >= 9900 - 100


def test_idle_directions_are_released_with_their_bytes() -> None:
    r = TcpReassembler(idle_records=50)
    out = r.segment("a:1", "b:2", 0, PSH_ACK, b"abc", 1, 0) + r.segment("a:1", "b:2", 10, PSH_ACK, b"xyz", 2, 0)
    for i in range(100):
        out += r.segment("c:1", "d:2", 3 * i, PSH_ACK, b"123", 3 + i, 0)
    assert r.tracked() == 1
    assert b"".join(p.data for p in out if p.src == "a:1") == b"abcxyz"
    assert [n.code for p in out for n in p.notes] == ["tcp-gap"]


def _peak(segments: int, syns: bool) -> int:
    """Peak bytes allocated (tracemalloc) while feeding `segments` segments of a flood."""
    r = TcpReassembler()
    r.max_directions = 200
    ended = getattr(r, "ended", None)
    tracemalloc.start()
    try:
        for k in range(segments):
            if ended is not None:
                ended.clear()  # as the dissector does: it lets the state of ended streams go
            if syns:  # a SYN with a new sequence number each time, on one 4-tuple, with data
                r.segment("10.3.0.1:40000", "10.0.0.2:5760", (k * 2_654_435_761) % (1 << 32), TCP_SYN, b"hb", k, 0)
            else:  # a new stream each time
                r.segment(f"10.3.{k // 65536}.{k % 256}:{k % 65536}", "10.0.0.2:5760", k, PSH_ACK, b"hb", k, 0)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("syns", [False, True], ids=["streams", "syn-generations"])
def test_memory_does_not_grow_with_the_number_of_streams(syns: bool) -> None:
    small, large = _peak(5_000, syns), _peak(20_000, syns)
    assert large < small * 1.5, (small, large)
