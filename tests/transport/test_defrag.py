"""IP fragment reassembly (mavscope.transport.defrag) by the receiving kernel's rules.

Where the expected answers come from:
- whole datagrams: built with scapy and cut by scapy's own `fragment()` / `fragment6()`, so what a complete
  reassembly must give is the datagram scapy built, byte for byte; the MAVLink frames in it are pymavlink's
  parse of that datagram's payload, and tshark (which reassembles IP) with pymavlink's Lua dissector finds the
  same frames in the same record (the record whose fragment completes the datagram);
- fragments that disagree: Linux's rules, read in net/ipv4/ip_fragment.c (ip_frag_queue), net/ipv6/reassembly.c
  (ip6_frag_queue) and net/ipv4/inet_fragment.c (inet_frag_queue_insert), worked by hand in each test's
  comment: the byte ranges are written out, and the bytes expected are the fragments' own, joined by hand.
"""

from __future__ import annotations

import json
import random
import struct
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink
from scapy.layers.inet import IP, UDP, fragment
from scapy.layers.inet6 import IPv6, IPv6ExtHdrFragment, fragment6, in6_chksum
from scapy.layers.l2 import Ether
from scapy.packet import Raw
from scapy.utils import wrpcap

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Dissector
from mavscope.transport.base import Payload
from mavscope.transport.decap import Decapsulator
from mavscope.transport.defrag import FRAGMENT_COST, MAX_DIST, QUEUE_COST, TIMEOUT_V4, TIMEOUT_V6, Defragmenter
from tests.support.builders import gcs_arm, gcs_heartbeat
from tests.support.cost import lines_run

MACS = {"src": "02:00:00:00:00:02", "dst": "02:00:00:00:00:01"}
GCS, VEHICLE = "10.0.0.2", "10.0.0.1"


FRAMES = gcs_heartbeat() + gcs_arm(1) + gcs_heartbeat() + gcs_arm(0)  # a ground station's, as pymavlink packs them


def pymavlink_frames(payload: bytes) -> list[tuple[int, int, int, int]]:
    """(seq, sysid, compid, msgid) of each frame pymavlink parses from `payload`."""
    m = mavlink.MAVLink(None)
    return [(f.get_seq(), f.get_srcSystem(), f.get_srcComponent(), f.get_msgId()) for f in m.parse_buffer(payload)]


def record(number: int, pkt: bytes, time: float = 0.0) -> Record:
    return Record(number, time, LINKTYPE_ETHERNET, bytes(pkt), number * 1000, len(pkt))


def raw4(off: int, data: bytes, more: bool, ident: int = 7, src: str = GCS, proto: int = 17) -> bytes:
    """An IPv4 fragment of datagram `ident` holding `data` at byte `off`."""
    return bytes(Ether(**MACS) / IP(src=src, dst=VEHICLE, id=ident, proto=proto, frag=off // 8,
                                    flags="MF" if more else 0) / Raw(data))


def raw6(off: int, data: bytes, more: bool, ident: int = 9) -> bytes:
    return bytes(Ether(**MACS) / IPv6(src="fd00::2", dst="fd00::1") / IPv6ExtHdrFragment(offset=off // 8, m=int(more),
                                                                                       id=ident, nh=17) / Raw(data))


def run(records: list[Record]) -> list[Payload]:
    d = Decapsulator()
    out = [p for r in records for p in d.feed(r)]
    return out + d.flush()


def codes(payloads: list[Payload]) -> list[list[str]]:
    return [[n.code for n in p.notes] for p in payloads if p.notes]


def datagram(payload: bytes, v6: bool = False) -> tuple[bytes, list[bytes]]:
    """(the UDP datagram scapy builds, its fragments as scapy cuts them, 40 bytes of data each at most)."""
    udp = UDP(sport=14550, dport=14555) / payload
    if v6:
        whole = IPv6(src="fd00::2", dst="fd00::1") / IPv6ExtHdrFragment(id=77) / udp
        return bytes(whole)[48:], [bytes(Ether(**MACS) / f) for f in fragment6(whole, 88)]
    whole = IP(src=GCS, dst=VEHICLE, id=4242) / udp
    return bytes(whole)[20:], [bytes(Ether(**MACS) / f) for f in fragment(whole, fragsize=40)]


# --- whole datagrams --------------------------------------------------------------------------------


@pytest.mark.parametrize("v6", [False, True], ids=["ipv4", "ipv6"])
@pytest.mark.parametrize("order", ["in-order", "reversed", "shuffled"])
def test_a_datagram_is_whole_in_any_order(v6: bool, order: str) -> None:
    whole, frags = datagram(FRAMES, v6)
    assert len(frags) >= 4
    numbered = list(enumerate(frags, 1))
    if order == "reversed":
        numbered.reverse()
    elif order == "shuffled":
        random.Random(3).shuffle(numbered)
    out = run([record(n, f) for n, f in numbered])
    assert len(out) == 1 and not out[0].notes
    p = out[0]
    assert p.data == whole[8:] == FRAMES  # the UDP payload scapy built
    assert p.record == numbered[-1][0]  # where the datagram is complete (tshark shows it there too)
    assert p.span == tuple(range(1, len(frags) + 1)) and p.offset is None
    assert (str(p.src), str(p.dst)) == (("[fd00::2]:14550", "[fd00::1]:14555") if v6 else
                                        (f"{GCS}:14550", f"{VEHICLE}:14555"))


def test_frames_of_a_fragmented_datagram(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """`read` shows the frames pymavlink parses from the whole datagram, at the record that completes it,
    reassembled from every fragment's record; `-w` writes those records, which reassemble again."""
    payload = FRAMES
    _, frags = datagram(payload)
    pcap = tmp_path / "frag.pcap"
    hb = bytes(Ether(**MACS) / IP(src=VEHICLE, dst=GCS) / UDP(sport=14555, dport=14550) / payload[:21])
    wrpcap(str(pcap), [Ether(b) for b in [hb, *reversed(frags), hb]])
    got = cli.jsonl(pcap)
    last = 1 + len(frags)  # the first fragment, sent last, completes the datagram
    assert [(f["frame"], f["seq"], f["sysid"], f["compid"], f["msgid"]) for f in got if f["frame"] == last] == [
        (last, *t) for t in pymavlink_frames(payload)]
    assert [f["frame"] for f in got] == [1, last, last, last, last, last + 1]
    status, out, _ = cli("read", pcap, "-V", "-Y", "COMMAND_LONG.param1 == 1")
    assert status == 0 and f"reassembled from records {', '.join(map(str, range(2, last + 1)))}" in out
    written = tmp_path / "arm.pcap"
    assert cli("read", pcap, "-Y", "COMMAND_LONG.param1 == 1", "-w", written).status == 0
    again = cli.jsonl(written)
    assert [(f["msgid"], f["fields"].get("param1")) for f in again] == [(0, None), (76, 1.0), (0, None), (76, 0.0)]


def test_tshark_reassembles_to_the_same_frames(tmp_path: Path, tshark_exe: str, lua_dissector: Path) -> None:
    from tests.support import tshark

    payload = FRAMES
    pcap = tmp_path / "frag.pcap"
    _, frags4 = datagram(payload)
    _, frags6 = datagram(payload, v6=True)
    wrpcap(str(pcap), [Ether(b) for b in [*frags4[::-1], *frags6]])
    run_ = tshark.run_lua_dissector(tshark_exe, lua_dissector, pcap, udp_ports={14555})
    theirs = [(f.frame, f.seq, f.sysid, f.compid, f.msgid) for f in run_.frames()]
    items = Dissector(_dialect()).run(_read(pcap))
    ours = [(f.record, f.seq, f.sysid, f.compid, f.msgid) for f in items if isinstance(f, Frame)]
    assert ours == theirs and len(ours) == 8


def _dialect():  # type: ignore[no-untyped-def]
    from mavscope.mavlink.dialect import load_dialect

    return load_dialect()


def _read(path: Path) -> list[Record]:
    from mavscope.capture.detect import open_capture

    with open_capture(path) as r:
        return list(r)


# --- fragments that disagree: Linux's rules -------------------------------------------------------------

A, B, C, LAST = bytes(range(16)), bytes(range(16, 32)), bytes(range(100, 116)), b"\xee" * 8
HEAD = struct.pack("!HHHH", 14550, 14555, 40, 0)  # the UDP header of a 40-byte datagram (8 + 32 bytes)


def head6(body: bytes) -> bytes:
    """The UDP header of `body` from fd00::2 to fd00::1, with the checksum IPv6 requires (scapy's in6_chksum;
    HEAD's 0, which IPv4 takes for none, is a wrong checksum there)."""
    udp = struct.pack("!HHHH", 14550, 14555, 8 + len(body), 0)
    value = in6_chksum(17, IPv6(src="fd00::2", dst="fd00::1"), udp + body) or 0xFFFF
    return udp[:6] + struct.pack("!H", value)


HEAD6 = head6(A[8:] + B + LAST)


def test_a_repeat_inside_a_run_is_a_duplicate_and_the_first_bytes_stay() -> None:
    """[0,16) then [16,32) arrive in order: one run [0,32). [8,24) with other bytes lies inside it:
    IPFRAG_DUP, dropped; the datagram completes with the first bytes when [32,40) comes."""
    first = HEAD + A[8:]  # bytes 0-15: the UDP header and 8 data bytes
    out = run([record(1, raw4(0, first, True)), record(2, raw4(16, B, True)), record(3, raw4(8, C, True)),
               record(4, raw4(32, LAST, False))])
    assert codes(out) == [["ip-fragment-conflict"]]
    assert out[0].record == 3 and "bytes 8-24" in out[0].notes[0].message
    assert out[1].data == A[8:] + B + LAST and out[1].span == (1, 2, 4)


def test_a_fragment_with_a_wrong_header_checksum_is_dropped_before_reassembly() -> None:
    """Linux checks the IPv4 header checksum (ip_rcv_core) before reassembly, so a first fragment whose checksum
    is wrong (scapy's is replaced) never reaches it, and a later first fragment with other bytes is no repeat:
    the datagram is made of it. Linux computes the header checksum in software, so a wrong one is not a
    sender's offload; 0 (what macOS and Windows leave to their NIC) is not judged, and that fragment is held."""
    bad = Ether(raw4(0, HEAD + A[8:], True))
    bad[IP].chksum = 0x1234
    out = run([record(1, bytes(bad)), record(2, raw4(0, HEAD + C[8:], True)), record(3, raw4(16, B + LAST, False))])
    assert codes(out) == [["ip-bad-checksum"]] and "drops this fragment before reassembly" in out[0].notes[0].message
    assert out[1].data == C[8:] + B + LAST and out[1].span == (2, 3)
    zero = Ether(raw4(0, HEAD + A[8:], True))
    zero[IP].chksum = 0
    out = run([record(1, bytes(zero)), record(2, raw4(0, HEAD + C[8:], True)), record(3, raw4(16, B + LAST, False))])
    assert codes(out) == [["ip-fragment-conflict"]] and out[1].data == A[8:] + B + LAST


def test_an_exact_repeat_is_a_duplicate_noted_as_chat() -> None:
    out = run([record(1, raw4(0, HEAD + A[8:], True)), record(2, raw4(0, HEAD + A[8:], True)),
               record(3, raw4(16, B + LAST, False))])
    assert codes(out) == [["ip-fragment-duplicate"]]
    assert out[1].data == A[8:] + B + LAST and out[1].record == 3


def test_the_same_bytes_in_another_order_are_an_overlap() -> None:
    """[16,32) first, then [0,16): inserted before it as a run of its own (Linux merges runs only at the
    tail). [8,24) now overlaps both runs partly: IPFRAG_OVERLAP, the whole datagram is discarded. [32,40)
    then starts a new datagram that never completes."""
    out = run([record(1, raw4(16, B, True)), record(2, raw4(0, HEAD + A[8:], True)),
               record(3, raw4(8, C, True)), record(4, raw4(32, LAST, False))])
    assert codes(out) == [["ip-fragment-overlap"], ["ip-fragment"]]
    assert out[0].record == 3 and "fragments in records 1, 2, 3" in out[0].notes[0].message
    assert out[1].record == 4 and all(not p.data for p in out)


def test_a_partial_overlap_at_the_tail_discards_the_datagram() -> None:
    """[0,16) then [8,24): it ends past the tail (16) but starts before it: IPFRAG_OVERLAP."""
    out = run([record(1, raw4(0, HEAD + A[8:], True)), record(2, raw4(8, C, True)),
               record(3, raw4(16, B + LAST, False))])
    assert codes(out) == [["ip-fragment-overlap"], ["ip-fragment"]]


def test_last_fragments_that_disagree_discard_the_datagram() -> None:
    """A last fragment ends the datagram at 40; a second last fragment ending at 48 is corrupt
    (INET_FRAG_LAST_IN and end != q.len): discard_qp. So is a middle fragment past the end."""
    out = run([record(1, raw4(32, LAST, False)), record(2, raw4(40, LAST, False))])
    assert codes(out) == [["ip-fragment-dropped"]] and "ending at 48" in out[0].notes[0].message
    out = run([record(1, raw4(32, LAST, False)), record(2, raw4(40, B, True))])
    assert codes(out) == [["ip-fragment-dropped"]] and "goes past the end" in out[0].notes[0].message


def test_a_middle_fragment_is_cut_to_eight_bytes_in_ipv4_and_dropped_in_ipv6() -> None:
    """IPv4: a middle fragment of 20 bytes is cut to 16 (`end &= ~7`), so [0,16) + [16,40) is whole.
    IPv6: ip6_frag_queue drops it (parameter problem) and keeps the datagram: the 16-byte one completes it."""
    out = run([record(1, raw4(0, HEAD + A[8:] + b"XXXX", True)), record(2, raw4(16, B + LAST, False))])
    assert codes(out) == [] and out[0].data == A[8:] + B + LAST
    out = run([record(1, raw6(0, HEAD6 + A[8:] + b"XXXX", True)), record(2, raw6(16, B + LAST, False)),
               record(3, raw6(0, HEAD6 + A[8:], True))])
    assert codes(out) == [["ip-fragment-dropped"]] and out[1].data == A[8:] + B + LAST and out[1].span == (2, 3)


def test_a_first_ipv6_fragment_must_hold_the_udp_header() -> None:
    """RFC 8200 4.5 (Linux: ipv6frag_thdr_truncated): a first fragment holding only a Destination Options
    header (8 bytes), with the UDP header in the next fragment, is dropped, so the datagram never completes.
    Cut 8 bytes later, the first fragment holds both headers and the datagram is read, past its option."""
    opts = bytes([17, 0, 1, 4, 0, 0, 0, 0])  # next header UDP, 8 bytes long, a PadN option
    body = opts + HEAD6 + A[8:] + B + LAST

    def frag6(off: int, chunk: bytes, more: bool) -> bytes:
        return bytes(Ether(**MACS) / IPv6(src="fd00::2", dst="fd00::1") / IPv6ExtHdrFragment(
            offset=off // 8, m=int(more), id=3, nh=60) / Raw(chunk))

    out = run([record(1, frag6(0, body[:8], True)), record(2, frag6(8, body[8:], False))])
    assert codes(out) == [["ip-fragment-dropped"], ["ip-fragment"]] and "upper-layer" in out[0].notes[0].message
    out = run([record(1, frag6(0, body[:16], True)), record(2, frag6(16, body[16:], False))])
    assert codes(out) == [] and out[0].data == A[8:] + B + LAST


def test_fragments_that_mix_ecn_codepoints_are_discarded() -> None:
    """ip_frag_reasm / ip6_frag_reasm: ip_frag_ecn_table gives 0xff (discard) for Not-ECT beside ECT(0),
    ECT(1) or CE; ECT(0) with CE is fine (the datagram is CE)."""
    def ecn4(off: int, chunk: bytes, more: bool, ecn: int) -> bytes:
        return bytes(Ether(**MACS) / IP(src=GCS, dst=VEHICLE, id=7, proto=17, tos=ecn, frag=off // 8,
                                        flags="MF" if more else 0) / Raw(chunk))

    def ecn6(off: int, chunk: bytes, more: bool, ecn: int) -> bytes:
        return bytes(Ether(**MACS) / IPv6(src="fd00::2", dst="fd00::1", tc=ecn) / IPv6ExtHdrFragment(
            offset=off // 8, m=int(more), id=9, nh=17) / Raw(chunk))

    for make, head in ((ecn4, HEAD), (ecn6, HEAD6)):
        out = run([record(1, make(0, head + A[8:], True, 0)), record(2, make(16, B + LAST, False, 1))])
        assert codes(out) == [["ip-fragment-dropped"]] and "mix ECN" in out[0].notes[0].message
        out = run([record(1, make(0, head + A[8:], True, 2)), record(2, make(16, B + LAST, False, 3))])
        assert codes(out) == [] and out[0].data == A[8:] + B + LAST


def test_a_dropped_fragment_starts_the_timer() -> None:
    """The receiver makes a datagram's queue, and starts its 60 s timer, before it drops an IPv6 middle
    fragment of 5 bytes (fq_find, then ip6_frag_queue). The next fragments, 59 and 61 s later, find the queue
    expired at 60 s with the second one in it: the third starts a new datagram that never completes."""
    out = run([record(1, raw6(16, B[:5], True), 0.0), record(2, raw6(0, HEAD + A[8:], True), 59.0),
               record(3, raw6(16, B + LAST, False), 61.0)])
    assert codes(out) == [["ip-fragment-dropped"], ["ip-fragment"], ["ip-fragment"]]
    assert f"not complete {TIMEOUT_V6:.0f} s" in out[1].notes[0].message and "records 1, 2" in out[1].notes[0].message


def test_nested_fragment_headers_and_jumbograms() -> None:
    """An atomic Fragment header (offset 0, no more) inside the fragmentable part is walked past (Linux's
    ipv6_skip_exthdr, then ipv6_frag_rcv's 'not fragmented'); a Fragment header in a packet of payload
    length 0 is dropped ('Jumbo payload inhibits frag. header')."""
    inner = bytes(IPv6ExtHdrFragment(nh=17, offset=0, m=0, id=5)) + HEAD6 + A[8:] + B + LAST

    def nested(off: int, chunk: bytes, more: bool) -> bytes:
        return bytes(Ether(**MACS) / IPv6(src="fd00::2", dst="fd00::1") / IPv6ExtHdrFragment(
            offset=off // 8, m=int(more), id=3, nh=44) / Raw(chunk))

    out = run([record(1, nested(0, inner[:24], True)), record(2, nested(24, inner[24:], False))])
    assert codes(out) == [] and out[0].data == A[8:] + B + LAST
    jumbo = bytearray(raw6(0, HEAD + A[8:], True))
    jumbo[14 + 4:14 + 6] = b"\x00\x00"  # payload length 0
    out = run([record(1, bytes(jumbo))])
    assert codes(out) == [["malformed-packet"]] and "payload length 0" in out[0].notes[0].message


def test_a_datagram_not_complete_in_time_is_discarded() -> None:
    """ipfrag_time: 30 s from the first fragment (IPv4). The second fragment, 31 s later, finds the first
    gone and starts a datagram of its own, which never completes."""
    late = TIMEOUT_V4 + 1
    out = run([record(1, raw4(0, HEAD + A[8:], True), 0.0), record(2, raw4(16, B + LAST, False), late)])
    assert codes(out) == [["ip-fragment"], ["ip-fragment"]]
    assert "not complete 30 s after its first fragment" in out[0].notes[0].message
    out = run([record(1, raw4(0, HEAD + A[8:], True), 0.0), record(2, raw4(16, B + LAST, False), TIMEOUT_V4)])
    assert codes(out) == [] and out[0].data == A[8:] + B + LAST


@pytest.mark.parametrize("others", [MAX_DIST - 1, MAX_DIST])
def test_too_many_fragments_from_the_source_in_between(others: int) -> None:
    """ip_frag_too_far: the source's fragment counter moved by more than ipfrag_max_dist (64) between two
    fragments of one datagram (the count includes the later fragment): 63 others in between are fine,
    64 start the datagram over."""
    noise = [record(2 + i, raw4(0, HEAD + A[8:], True, ident=1000 + i)) for i in range(others)]
    out = run([record(1, raw4(0, HEAD + A[8:], True)), *noise, record(2 + others, raw4(16, B + LAST, False))])
    whole = [p for p in out if p.data]
    if others < MAX_DIST:
        assert len(whole) == 1 and whole[0].data == A[8:] + B + LAST
    else:
        assert not whole and "ipfrag_max_dist" in out[0].notes[0].message and out[0].record == 2 + others


def test_every_fragment_is_dropped_while_the_fragments_held_are_over_the_limit() -> None:
    """ipfrag_high_thresh: over it, inet_frag_find finds no datagram at all, so every fragment is dropped,
    a datagram's own last one too, until the timer discards datagrams (30 s) and frees the hold."""
    d = Decapsulator()
    d.defrag = Defragmenter(max_held=1500)  # two fragments of 16 bytes and their overhead pass it
    got = [d.feed(record(n, raw4(0, HEAD + A[8:], True, ident=n), 0.0)) for n in (1, 2, 3)]
    assert got[:2] == [[], []] and [n.code for n in got[2][0].notes] == ["ip-fragment-dropped"]
    late = d.feed(record(4, raw4(16, B + LAST, False, ident=1), 1.0))
    assert [n.code for n in late[0].notes] == ["ip-fragment-dropped"] and not late[0].data
    after = d.feed(record(5, raw4(0, HEAD + A[8:], True, ident=9), 31.0)) + d.feed(record(6, raw4(
        16, B + LAST, False, ident=9), 31.0))
    assert [n.code for p in after for n in p.notes] == ["ip-fragment", "ip-fragment"]  # the two expired
    assert after[-1].data == A[8:] + B + LAST and after[-1].span == (5, 6)


def test_a_datagram_over_65535_bytes_is_discarded() -> None:
    """ip_frag_reasm: the header (20) and 65,528 bytes of fragments make 65,548 > 65,535: out_oversize."""
    body = bytes(8184)
    frags = [record(1 + i, raw4(i * 8184, body, True)) for i in range(8)]  # [0, 65472)
    out = run([*frags, record(9, raw4(65472, bytes(56), False))])
    assert codes(out) == [["ip-fragment-dropped"]] and "65548 bytes long" in out[0].notes[0].message


def test_a_snapped_fragment_is_said_to_be_incomplete_in_the_capture() -> None:
    pkt = raw4(0, HEAD + A[8:] + B, True)
    snapped = Record(1, 0.0, LINKTYPE_ETHERNET, pkt[:-10], 1000, len(pkt))
    out = run([snapped, record(2, raw4(32, LAST, False))])
    assert codes(out) == [["ip-fragment"], ["ip-fragment"]]
    assert "the capture holds 22 of its 32 bytes" in out[0].notes[0].message


def test_both_engines_agree_on_fragments(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The native walker hands every fragment to Python: read and stats are the same with MAVSCOPE_PURE."""
    payload = FRAMES
    _, frags4 = datagram(payload)
    _, frags6 = datagram(payload, v6=True)
    hb = bytes(Ether(**MACS) / IP(src=VEHICLE, dst=GCS) / UDP(sport=14555, dport=14550) / payload[:21])
    disagree = [raw4(16, B, True, ident=5), raw4(0, HEAD + A[8:], True, ident=5), raw4(8, C, True, ident=5)]
    pcap = tmp_path / "mixed.pcap"
    wrpcap(str(pcap), [Ether(b) for b in [hb, *frags4[::-1], hb, *disagree, *frags6, hb, frags4[0]]])
    for argv in (("read", pcap, "-T", "jsonl"), ("stats", pcap, "--json"), ("read", pcap, "-V")):
        native = cli(*argv, environ={"MAVSCOPE_PURE": "0"})
        pure = cli(*argv, environ={"MAVSCOPE_PURE": "1"})
        assert native == pure
    assert "overlaps a fragment held" in cli("read", pcap).err


def test_reassembly_work_is_linear() -> None:
    """A datagram in fragments of 8 bytes that never completes (bytes 8-15 never come), sent in reverse
    order (each goes before all the others held), then each again: the work per fragment does not grow
    with the fragments held (counted, not timed)."""

    def work(n: int) -> int:
        recs = [record(i + 1, raw4((n - 1 - i) * 8, bytes(8), i != 0)) for i in range(n - 2)]
        recs.append(record(n - 1, raw4(0, bytes(8), True)))
        recs += [record(n + i, raw4(i * 8, bytes(8), True)) for i in range(2, n)]
        d = Decapsulator()
        return lines_run(lambda: [d.feed(r) for r in recs])

    small, large = work(500), work(4000)
    assert large < 8 * small * 1.25


def test_fragments_that_disagree_are_security_findings(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """`audit` reports the overlap (record 3) and the conflicting repeat (record 6) and exits 1; the export's
    findings table has them on both batch sources."""
    from mavscope.export.source import ExportOptions, record_batches

    pcap = tmp_path / "evasion.pcap"
    overlap = [raw4(16, B, True, ident=5), raw4(0, HEAD + A[8:], True, ident=5), raw4(8, C, True, ident=5)]
    conflict = [raw4(0, HEAD + A[8:], True, ident=6), raw4(16, B, True, ident=6), raw4(8, C, True, ident=6),
                raw4(32, LAST, False, ident=6)]
    wrpcap(str(pcap), [Ether(b) for b in overlap + conflict])
    status, out, _ = cli("audit", pcap, "--json")
    found = {f["code"]: f["frames"] for f in json.loads(out)["findings"]}
    assert status == 1 and found == {"ip-fragment-overlap": [3], "ip-fragment-conflict": [6]}
    for source in ("python", "native"):
        options = ExportOptions(source=source, tables=frozenset({"findings"}))
        rows = [b.to_pylist() for b in record_batches(pcap, options)]
        assert sorted((r["code"], r["frames"]) for batch in rows for r in batch) == [
            ("ip-fragment-conflict", [6]), ("ip-fragment-overlap", [3])], source


@settings(max_examples=150, deadline=None, derandomize=True)
@given(st.data())
def test_any_cut_in_any_order_with_repeats_gives_the_datagram(data: st.DataObject) -> None:
    """Property: a datagram cut anywhere on 8-byte bounds, its fragments sent in any order, some sent twice
    (same bytes) before the last, is the datagram again at the last record, with a chat note per repeat;
    without one of its fragments it never is, and one `ip-fragment` note says so at the end. The expected
    bytes are the datagram's own."""
    v6 = data.draw(st.booleans(), "v6")
    whole = (head6(FRAMES) if v6 else HEAD[:4] + struct.pack("!H", 8 + len(FRAMES)) + HEAD[6:]
             ) + FRAMES
    cuts = sorted(data.draw(st.sets(st.integers(1, (len(whole) - 1) // 8), min_size=1, max_size=12), "cuts"))
    bounds = [0, *(c * 8 for c in cuts), len(whole)]
    pieces = [(a, whole[a:b], b == len(whole)) for a, b in zip(bounds, bounds[1:])]
    order = data.draw(st.permutations(range(len(pieces))), "order")
    repeats = data.draw(st.lists(st.sampled_from(range(len(pieces))), max_size=4), "repeats")
    drop = data.draw(st.none() | st.sampled_from(range(len(pieces))), "drop")
    sent = [i for i in order if i != drop]
    dups = 0
    for r in repeats:  # a repeat goes after its first sending and before the piece sent last
        if r != drop and r != sent[-1]:
            sent.insert(data.draw(st.integers(sent.index(r) + 1, len(sent) - 1), "at"), r)
            dups += 1
    make = raw6 if v6 else raw4
    records = [record(n, make(pieces[i][0], pieces[i][1], not pieces[i][2])) for n, i in enumerate(sent, 1)]
    out = run(records)
    datagrams = [p for p in out if p.data]
    assert all(n.code in ("ip-fragment-duplicate", "ip-fragment") for p in out for n in p.notes)
    if drop is not None:
        assert not datagrams and [p.notes[-1].code for p in out if p.notes][-1:] == ["ip-fragment"]
        return
    assert len(datagrams) == 1 and datagrams[0].data == whole[8:] and datagrams[0].record == len(sent)
    assert sum(n.code == "ip-fragment-duplicate" for p in out for n in p.notes) == dups


def fast4(ident: int, off: int, more: bool, data: bytes) -> bytes:
    """An IPv4 fragment, packed by hand (the hypothesis test below builds thousands)."""
    flags = (0x2000 if more else 0) | off // 8
    return bytes(12) + b"\x08\x00" + struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(data), ident, flags, 64, 17, 0,
                                                bytes(4), bytes(4)) + data


def fast6(ident: int, off: int, more: bool, data: bytes) -> bytes:
    return bytes(12) + b"\x86\xdd" + struct.pack("!IHBB16s16s", 6 << 28, 8 + len(data), 44, 64, bytes(16),
                                                bytes(16)) + struct.pack("!BxHI", 17, off | more, ident) + data


@settings(max_examples=150, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 40), st.integers(0, 24), st.booleans(), st.booleans(),
                          st.floats(0, 100)), max_size=60))
def test_hostile_fragments_never_raise_and_stay_within_the_hold(frags: list[tuple[int, int, int, bool, bool,
                                                                                   float]]) -> None:
    """Any mix of fragments (4 datagrams, offsets 0-320, lengths 0-24, both versions, times out of order):
    no exception, and the bytes held never pass the limit by more than one fragment."""
    d = Decapsulator()
    d.defrag = Defragmenter(max_held=4000)
    for n, (ident, off, size, more, v6, t) in enumerate(frags, 1):
        d.feed(record(n, (fast6 if v6 else fast4)(ident, off * 8, more, bytes(range(size))), t))
        assert d.defrag.held <= 4000 + 24 + FRAGMENT_COST + QUEUE_COST
    d.flush()
    assert d.defrag.held == 0 and not d.defrag.pending


def test_a_frame_in_many_fragments_names_the_first_records(cli, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """`read -V` names 8 of a frame's records and counts the rest (each frame of a datagram in thousands of
    fragments named them all: 74 MB of text for a 268 kB capture)."""
    whole = HEAD[:4] + struct.pack("!H", 8 + len(FRAMES)) + HEAD[6:] + FRAMES
    cuts = list(range(0, len(whole), 8))
    pcap = tmp_path / "many.pcap"
    wrpcap(str(pcap), [Ether(raw4(a, whole[a:a + 8], a + 8 < len(whole))) for a in cuts])
    status, out, _ = cli("read", pcap, "-V", "-c", "1")
    n = len(cuts)
    assert status == 0 and f"reassembled from records 1, 2, 3, 4, 5, 6, 7, 8 and {n - 8} more, to record {n}" in out
