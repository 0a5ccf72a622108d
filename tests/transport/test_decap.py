"""Decapsulator: link types, IPv4/IPv6, UDP, notes for what cannot be decoded."""

from __future__ import annotations

import struct

import pytest
from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.inet6 import IPv6, IPv6ExtHdrDestOpt, IPv6ExtHdrFragment, IPv6ExtHdrHopByHop
from scapy.layers.l2 import ARP, CookedLinux, Dot1AD, Dot1Q, Ether

from mavscope.capture.base import (
    LINKTYPE_ETHERNET,
    LINKTYPE_IPV4,
    LINKTYPE_IPV6,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_LOOP,
    LINKTYPE_MAVLINK_RAW,
    LINKTYPE_MAVLINK_TLOG,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
    Record,
)
from mavscope.notes import note
from mavscope.transport.base import Payload
from mavscope.transport.decap import Decapsulator

MAV = b"\xfd\x09\x00\x00\x01\x01\x01\x00\x00\x00" + bytes(9) + b"\x12\x34"
UDP4 = IP(src="10.1.2.3", dst="10.9.8.7") / UDP(sport=14550, dport=14540) / MAV
UDP6 = IPv6(src="fe80::1", dst="2001:db8::2") / UDP(sport=14550, dport=14540) / MAV


def rec(data: bytes, linktype: int = LINKTYPE_ETHERNET, number: int = 1, offset: int = 1000) -> Record:
    return Record(number, 1.0, linktype, bytes(data), offset, len(data))


def one(payloads: list[Payload]) -> Payload:
    assert len(payloads) == 1, payloads
    return payloads[0]


def test_ethernet_ipv4_udp_fast_path() -> None:
    p = one(Decapsulator().feed(rec(Ether() / UDP4)))
    assert (p.transport, str(p.src), str(p.dst)) == ("udp", "10.1.2.3:14550", "10.9.8.7:14540")
    assert (p.data, p.stream) == (MAV, None)
    assert p.offset == 1000 + 42 and p.record == 1 and p.notes == ()


@pytest.mark.parametrize("tags", [Dot1Q(vlan=5), Dot1AD(vlan=7) / Dot1Q(vlan=5)])
def test_vlan_and_qinq(tags: object) -> None:
    p = one(Decapsulator().feed(rec(Ether() / tags / UDP4)))
    assert p.data == MAV and str(p.src) == "10.1.2.3:14550"


def test_ethernet_padding_is_stripped() -> None:
    short = IP(src="1.2.3.4", dst="5.6.7.8") / UDP(sport=1, dport=2) / b"\xfe\x00"
    frame = bytes(Ether() / short) + b"\0" * 16  # padded up to the 60-byte Ethernet minimum
    assert one(Decapsulator().feed(rec(frame))).data == b"\xfe\x00"


def test_wrong_checksums_do_not_drop() -> None:
    bad = IP(src="10.1.2.3", dst="10.9.8.7", chksum=0x1234) / UDP(sport=1, dport=2, chksum=0xDEAD) / MAV
    assert one(Decapsulator().feed(rec(Ether() / bad))).data == MAV


def test_ipv4_options_take_the_slow_path() -> None:
    opt = IP(src="10.1.2.3", dst="10.9.8.7", options=b"\x01\x01\x01\x00") / UDP(sport=1, dport=2) / MAV
    p = one(Decapsulator().feed(rec(Ether() / opt)))
    assert p.data == MAV and p.offset == 1000 + 14 + 24 + 8


def test_sll_and_sll2() -> None:
    sll = bytes(CookedLinux(proto=0x0800) / UDP4)
    assert one(Decapsulator().feed(rec(sll, LINKTYPE_LINUX_SLL))).data == MAV
    sll2 = struct.pack("!HHIHBB8s", 0x86DD, 0, 3, 1, 0, 6, b"\x02" * 6) + bytes(UDP6)
    p = one(Decapsulator().feed(rec(sll2, LINKTYPE_LINUX_SLL2)))
    assert p.data == MAV and str(p.src) == "[fe80::1]:14550" and str(p.dst) == "[2001:db8::2]:14540"


@pytest.mark.parametrize("endian", ["<", ">"])
@pytest.mark.parametrize(("af", "payload"), [(2, UDP4), (24, UDP6), (28, UDP6), (30, UDP6)])
def test_bsd_null_both_byte_orders(endian: str, af: int, payload: object) -> None:
    data = struct.pack(endian + "I", af) + bytes(payload)
    assert one(Decapsulator().feed(rec(data, LINKTYPE_NULL))).data == MAV


def test_loop_raw_ipv4_ipv6() -> None:
    d = Decapsulator()
    assert one(d.feed(rec(struct.pack(">I", 2) + bytes(UDP4), LINKTYPE_LOOP))).data == MAV
    assert one(d.feed(rec(bytes(UDP4), LINKTYPE_RAW))).data == MAV
    assert one(d.feed(rec(bytes(UDP6), LINKTYPE_RAW))).data == MAV
    assert one(d.feed(rec(bytes(UDP4), LINKTYPE_IPV4))).data == MAV
    assert one(d.feed(rec(bytes(UDP6), LINKTYPE_IPV6))).data == MAV


def test_ipv6_extension_headers() -> None:
    pkt = (IPv6(src="::1", dst="::1") / IPv6ExtHdrHopByHop() / IPv6ExtHdrDestOpt()
           / UDP(sport=5, dport=14550) / MAV)
    p = one(Decapsulator().feed(rec(Ether() / pkt)))
    assert p.data == MAV and str(p.src) == "[::1]:5"


def test_lone_fragments_are_held_then_noted() -> None:
    """A fragment is held for reassembly (mavscope.transport.defrag, tested in test_defrag.py); one whose
    datagram never completes is noted at the end of the capture, on its record, naming the datagram."""
    d = Decapsulator()
    frag4 = IP(src="1.1.1.1", dst="2.2.2.2", flags="MF", id=77) / UDP(sport=1, dport=2) / MAV
    assert d.feed(rec(Ether(src="02:00:00:00:00:02", dst="02:00:00:00:00:01") / frag4, number=1)) == []
    later = IP(src="1.1.1.1", dst="2.2.2.2", frag=5, id=77, proto=17) / MAV  # bytes 24-39 never come
    assert d.feed(rec(Ether(src="02:00:00:00:00:02", dst="02:00:00:00:00:01") / later, number=2)) == []
    frag6 = IPv6(src="::1", dst="::2") / IPv6ExtHdrFragment(m=1, id=9) / UDP(sport=1, dport=2) / (MAV + bytes(3))
    assert d.feed(rec(Ether(src="02:00:00:00:00:02", dst="02:00:00:00:00:01") / frag6, number=3)) == []
    left = d.flush()
    assert [(p.record, p.data, [n.code for n in p.notes]) for p in left] == [
        (2, b"", ["ip-fragment"]), (3, b"", ["ip-fragment"])]
    assert "IPv4 datagram id 77 from 1.1.1.1 to 2.2.2.2, fragments in records 1, 2" in left[0].notes[0].message
    assert "IPv6 datagram id 9 from ::1 to ::2, fragments in record 3" in left[1].notes[0].message


def test_malformed_headers_become_notes() -> None:
    d = Decapsulator()
    cases = [
        bytes(Ether() / UDP4)[:30],  # IPv4 header cut
        bytes(Ether(type=0x0800)) + b"\x46" + bytes(UDP4)[1:20],  # IHL says options that are not there
        bytes(Ether() / IP(src="1.1.1.1", dst="2.2.2.2", proto=17) / b"\x00\x01"),  # UDP header cut
        bytes(Ether() / IP(src="1.1.1.1", dst="2.2.2.2") / UDP(sport=1, dport=2, len=4)),  # UDP length < 8
        bytes(Ether() / IP(src="1.1.1.1", dst="2.2.2.2") / TCP(dataofs=15)),  # TCP header longer than packet
        b"\x00" * 10,  # Ethernet header cut
    ]
    for i, data in enumerate(cases):
        p = one(d.feed(rec(data, offset=500)))
        assert p.data == b"" and p.notes[0].code == "malformed-packet", (i, p)
        assert p.notes[0].offset is not None and p.notes[0].offset >= 500


def test_non_udp_tcp_yields_nothing() -> None:
    d = Decapsulator()
    assert d.feed(rec(Ether() / ARP())) == []
    assert d.feed(rec(Ether() / IP(src="1.1.1.1", dst="2.2.2.2", proto=1) / b"ping")) == []


def test_unknown_linktype_noted_once() -> None:
    d = Decapsulator()
    p = one(d.feed(rec(b"whatever", linktype=147)))
    assert p.notes[0].code == "unknown-linktype" and p.data == b""
    assert d.feed(rec(b"whatever", linktype=147)) == []
    assert one(d.feed(rec(b"x", linktype=148))).notes[0].code == "unknown-linktype"


def test_record_notes_are_carried() -> None:
    d = Decapsulator()
    snapped = note("record-snapped", "cut", 10)
    r = Record(4, 1.0, LINKTYPE_ETHERNET, bytes(Ether() / UDP4), 0, 5000, (snapped,))
    assert one(d.feed(r)).notes == (snapped,)
    r = Record(5, 1.0, LINKTYPE_ETHERNET, bytes(Ether() / ARP()), 0, 60, (snapped,))
    p = one(d.feed(r))
    assert p.notes == (snapped,) and p.data == b"" and p.record == 5


def test_tlog_and_raw_pass_through() -> None:
    d = Decapsulator()
    t = one(d.feed(Record(1, 2.0, LINKTYPE_MAVLINK_TLOG, MAV, 8, len(MAV))))
    assert (t.transport, t.src, t.dst, t.stream, t.data, t.offset) == ("tlog", None, None, None, MAV, 8)
    r = one(d.feed(Record(2, None, LINKTYPE_MAVLINK_RAW, MAV, 0, len(MAV))))
    assert r.transport == "raw" and r.stream == ("raw",) and r.data == MAV


def test_plain_ethernet_ipv4_udp_takes_the_fast_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """A guard against the fast path silently falling back to the general one (no timing involved)."""
    d = Decapsulator()
    slow_calls = []
    general = d._slow
    monkeypatch.setattr(d, "_slow", lambda rec: slow_calls.append(rec) or general(rec))
    r = rec(Ether() / UDP4)
    fast = one(d.feed(r))
    assert slow_calls == []
    assert one(Decapsulator()._slow(r)) == fast  # the general path gives the same Payload
    d.feed(rec(struct.pack("<I", 2) + bytes(UDP4), LINKTYPE_NULL))
    assert len(slow_calls) == 1  # other link types take it
