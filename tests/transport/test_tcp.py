"""TCP reassembly: order, retransmissions, overlaps, gaps, wraparound, new connections; the real TCP capture."""

from __future__ import annotations

from pathlib import Path

from mavscope.capture.detect import open_capture
from mavscope.transport.decap import Decapsulator
from mavscope.transport.tcp import TCP_FIN, TCP_RST, TCP_SYN, TcpReassembler

A, B = "10.0.0.1:5760", "10.0.0.2:40000"


def feed(r: TcpReassembler, seq: int, data: bytes, flags: int = 0, record: int = 1, offset: int | None = 100):
    return r.segment(A, B, seq % (1 << 32), flags, data, record, offset)


def stream(payloads: list) -> bytes:
    return b"".join(p.data for p in payloads)


def codes(payloads: list) -> list[str]:
    return [n.code for p in payloads for n in p.notes]


def test_in_order_from_syn() -> None:
    r = TcpReassembler()
    assert feed(r, 1000, b"", TCP_SYN) == []
    out = feed(r, 1001, b"hello", record=2, offset=54) + feed(r, 1006, b" world", record=3, offset=200)
    assert stream(out) == b"hello world"
    assert [(p.record, p.offset, p.stream) for p in out] == [(2, 54, ("tcp", A, B, 0)), (3, 200, ("tcp", A, B, 0))]
    assert all(p.src == A and p.dst == B and p.transport == "tcp" for p in out)


def test_out_of_order_is_buffered_then_delivered() -> None:
    r = TcpReassembler()
    out = feed(r, 0, b"abc")
    assert feed(r, 6, b"ghi", record=3) == []
    out += feed(r, 3, b"def", record=2)
    assert stream(out) == b"abcdefghi" and [p.record for p in out] == [1, 2, 3] and not codes(out)


def test_retransmission_dropped_with_note() -> None:
    r = TcpReassembler()
    out = feed(r, 0, b"abcdef")
    again = feed(r, 0, b"abcdef", record=2)
    assert stream(again) == b"" and codes(again) == ["tcp-retransmission"]
    assert stream(out + again + feed(r, 6, b"gh")) == b"abcdefgh"


def test_partial_overlap_is_trimmed_and_offset_moves() -> None:
    r = TcpReassembler()
    assert stream(feed(r, 0, b"abcdef")) == b"abcdef"
    more = feed(r, 4, b"efghij", record=2, offset=500)
    assert stream(more) == b"ghij" and more[0].offset == 502 and codes(more) == ["tcp-retransmission"]


def test_a_retransmission_with_other_bytes_is_a_conflict() -> None:
    """A receiving TCP (Linux's tcp_data_queue) drops bytes it has delivered: what it read first stays. A
    retransmission carrying other bytes there is a `tcp-conflict` (a monitor taking the retransmission reads
    another stream), whole or overlapping, and is compared over the last TAIL bytes delivered (by hand: the
    segments below differ from what was delivered at the byte named)."""
    r = TcpReassembler()
    feed(r, 0, b"abcdef")
    again = feed(r, 0, b"abcXef", record=2)
    assert stream(again) == b"" and codes(again) == ["tcp-conflict"] and "from its byte 3" in again[0].notes[0].message
    more = feed(r, 4, b"eFghij", record=3, offset=500)
    assert stream(more) == b"ghij" and codes(more) == ["tcp-conflict"] and "from its byte 1" in more[0].notes[0].message
    same = feed(r, 2, b"cdefgh", record=4)
    assert codes(same) == ["tcp-retransmission"]
    late = feed(r, 100, b"later", record=5) + feed(r, 10, b"k" * 90, record=6)  # out of order, then in order
    assert stream(late) == b"k" * 90 + b"later" and not codes(late)
    assert codes(feed(r, 10, b"k" * 89 + b"!", record=7)) == ["tcp-conflict"]


def test_bytes_older_than_the_tail_are_not_compared() -> None:
    r = TcpReassembler()
    feed(r, 0, b"x" * 2000)
    old = feed(r, 0, b"y" * 100, record=2)
    assert codes(old) == ["tcp-retransmission"] and "100 of them older than the last 512" in old[0].notes[0].message
    assert codes(feed(r, 1000, b"x" * 999 + b"y", record=3)) == ["tcp-conflict"]


def test_gap_skipped_on_flush_with_byte_count() -> None:
    r = TcpReassembler()
    out = feed(r, 0, b"abc") + feed(r, 10, b"xyz")
    assert stream(out) == b"abc"
    rest = r.flush()
    assert stream(rest) == b"xyz" and codes(rest) == ["tcp-gap"] and "7 bytes missing" in rest[0].notes[0].message


def test_gap_skipped_on_fin_and_rst() -> None:
    for flag in (TCP_FIN, TCP_RST):
        r = TcpReassembler()
        out = feed(r, 0, b"abc") + feed(r, 5, b"fg") + feed(r, 7, b"", flag)
        assert stream(out) == b"abcfg" and codes(out) == ["tcp-gap"]


def test_buffer_bound_forces_the_gap() -> None:
    r = TcpReassembler(max_buffered=100)
    out = feed(r, 0, b"a")
    for i in range(5):
        out += feed(r, 11 + 30 * i, b"x" * 30)
    assert stream(out) == b"a" + b"x" * 150 and codes(out) == ["tcp-gap"]


def test_sequence_wraparound() -> None:
    r = TcpReassembler()
    isn = (1 << 32) - 3
    out = feed(r, isn, b"", TCP_SYN) + feed(r, isn + 1, b"ab") + feed(r, isn + 5, b"ef") + feed(r, isn + 3, b"cd")
    assert stream(out) == b"abcdef" and not codes(out)


def test_new_syn_starts_a_new_stream() -> None:
    r = TcpReassembler()
    first = feed(r, 100, b"", TCP_SYN) + feed(r, 101, b"old")
    assert feed(r, 100, b"", TCP_SYN) == []  # a retransmitted SYN changes nothing
    second = feed(r, 9000, b"", TCP_SYN) + feed(r, 9001, b"new")
    assert first[0].stream != second[0].stream and second[0].data == b"new"
    assert second[0].stream == ("tcp", A, B, 1)


def test_directions_are_separate() -> None:
    r = TcpReassembler()
    a = r.segment(A, B, 0, 0, b"ping", 1, 0)
    b = r.segment(B, A, 0, 0, b"pong", 2, 0)
    assert a[0].stream != b[0].stream and (b[0].src, b[0].dst) == (B, A)


def test_real_tcp_capture_reassembles_seven_frames(real_captures: Path) -> None:
    from pymavlink.dialects.v20 import all as mavall

    d = Decapsulator()
    with open_capture(real_captures / "judep90_serial_over_tcp_socat.pcapng") as reader:
        assert reader.kind == "pcapng"
        payloads = [p for rec in reader for p in d.feed(rec)] + d.flush()
    streams = {p.stream for p in payloads if p.data}
    assert len(streams) == 1 and all(":5760" in str(p.src) for p in payloads if p.data)
    mav = mavall.MAVLink(None)
    mav.robust_parsing = True
    msgs = [m for m in mav.parse_buffer(stream(payloads)) or [] if not isinstance(m, mavall.MAVLink_bad_data)]
    assert len(msgs) == 7 and all(m.get_header().mlen is not None for m in msgs)


def test_real_udp_capture(real_captures: Path) -> None:
    from pymavlink.dialects.v20 import all as mavall

    d = Decapsulator()
    with open_capture(real_captures / "ipal_transcriber_MAVLink.pcap") as reader:
        payloads = [p for rec in reader for p in d.feed(rec)] + d.flush()
    assert all(p.transport == "udp" and not p.notes for p in payloads)
    assert len(payloads) == 10  # PROVENANCE.md: 10 frames, one per datagram
    assert all(14550 in (p.src.port, p.dst.port) for p in payloads)
    assert sum(p.dst.port == 14550 for p in payloads) == 9
    mav = mavall.MAVLink(None)
    mav.robust_parsing = True
    frames = [m for p in payloads for m in mav.parse_buffer(p.data) or [] if not isinstance(m, mavall.MAVLink_bad_data)]
    assert len(frames) == 10


def test_a_conflicting_retransmission_is_an_audit_finding(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """An ARM over TCP, then a 'retransmission' of its bytes carrying a disarm: the stream keeps the ARM
    (pymavlink's packing of it, parsed back by pymavlink), the retransmission is a tcp-conflict, and `audit`
    reports it (exit 1)."""
    from pymavlink.dialects.v20 import common as mavlink
    from scapy.layers.inet import IP, TCP
    from scapy.layers.l2 import Ether
    from scapy.utils import wrpcap

    gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    arm = gcs.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(gcs)
    gcs.seq = 0
    disarm = gcs.command_long_encode(1, 1, 400, 0, 0, 0, 0, 0, 0, 0, 0).pack(gcs)
    assert len(arm) != len(disarm) or arm != disarm
    mac = {"src": "02:00:00:00:00:02", "dst": "02:00:00:00:00:01"}
    ip = IP(src="10.0.0.2", dst="10.0.0.1")
    pkts = [Ether(**mac) / ip / TCP(sport=40000, dport=5760, flags="S", seq=999),
            Ether(**mac) / ip / TCP(sport=40000, dport=5760, flags="PA", seq=1000) / arm,
            Ether(**mac) / ip / TCP(sport=40000, dport=5760, flags="PA", seq=1000) / disarm]
    pcap = tmp_path / "tcp_conflict.pcap"
    wrpcap(str(pcap), pkts)
    frames = cli.jsonl(pcap)
    m = mavlink.MAVLink(None)
    assert [(f["msgid"], f["fields"]["param1"]) for f in frames] == [
        (x.get_msgId(), x.param1) for x in m.parse_buffer(arm)] == [(76, 1.0)]
    status, out, err = cli("audit", pcap, "--json")
    import json

    assert status == 1 and [(f["code"], f["frames"]) for f in json.loads(out)["findings"]] == [("tcp-conflict", [3])]
    assert "with other bytes" in err


def test_a_conflict_is_named_by_its_own_record(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """A conflicting retransmission (record 3) followed by more of the stream: the finding names record 3,
    the segment that carried the other bytes, not the HEARTBEAT of record 4 (the stream's next frame, which
    carried the note before stop 33); the frames are the ARM and two HEARTBEATs, as pymavlink parses the
    bytes the receiver kept."""
    import json

    from pymavlink.dialects.v20 import common as mavlink
    from scapy.layers.inet import IP, TCP
    from scapy.layers.l2 import Ether
    from scapy.utils import wrpcap

    gcs = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    arm = gcs.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(gcs)
    gcs.seq = 0
    disarm = gcs.command_long_encode(1, 1, 400, 0, 0, 0, 0, 0, 0, 0, 0).pack(gcs)
    hb = gcs.heartbeat_encode(6, 8, 0, 0, 4).pack(gcs)
    mac = {"src": "02:00:00:00:00:02", "dst": "02:00:00:00:00:01"}
    ip = IP(src="10.0.0.2", dst="10.0.0.1")

    def seg(flags: str, seq: int, data: bytes = b"") -> Ether:
        return Ether(**mac) / ip / TCP(sport=40000, dport=5760, flags=flags, seq=seq) / data

    pcap = tmp_path / "conflict_mid.pcap"
    wrpcap(str(pcap), [seg("S", 999), seg("PA", 1000, arm), seg("PA", 1000, disarm), seg("PA", 1000 + len(arm), hb),
                       seg("PA", 1000 + len(arm) + len(hb), hb)])
    m = mavlink.MAVLink(None)
    frames = cli.jsonl(pcap)
    assert [(f["frame"], f["msgid"]) for f in frames] == list(zip((2, 4, 5), (x.get_msgId() for x in
                                                                                m.parse_buffer(arm + hb + hb))))
    assert not any(f.get("notes") for f in frames)
    status, out, err = cli("audit", pcap, "--json")
    assert status == 1 and [(f["code"], f["frames"]) for f in json.loads(out)["findings"]] == [("tcp-conflict", [3])]
    assert "record 3: " in err
