"""Damaged input never raises: truncation at every byte, bit flips and absurd lengths become notes."""

from __future__ import annotations

import itertools
import os
import struct
import tempfile

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavscope.capture.base import (
    LINKTYPE_ETHERNET,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_LINUX_SLL2,
    LINKTYPE_NULL,
    LINKTYPE_RAW,
    Record,
)
from mavscope.capture.detect import open_capture
from mavscope.capture.synth import udp_packet
from mavscope.capture.writer import PcapngWriter
from mavscope.notes import CODES
from mavscope.transport.base import Payload
from mavscope.transport.decap import Decapsulator
from tests.support.builders import pcap_bytes, tlog_spaced

FUZZ = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
T0 = 1_700_000_000.0
PACKETS = [udp_packet("10.0.0.1", 14550, "10.0.0.2", 14540, bytes([0xFD, i]) * (i + 3)) for i in range(3)]
FRAMES = [bytes([0xFD, 3, 0, 0, i, 1, 1, 0, 0, 0, 1, 2, 3, 0xAA, 0xBB]) for i in range(3)]


def _pcap() -> tuple[bytes, list[int]]:
    content = pcap_bytes((T0 + i, p) for i, p in enumerate(PACKETS))
    ends, pos = [24], 24
    for p in PACKETS:
        pos += 16 + len(p)
        ends.append(pos)
    return content, ends


def _pcapng() -> tuple[bytes, list[int]]:
    import io

    buf = io.BytesIO()
    with PcapngWriter(buf, nanosecond=True) as w:
        for i, p in enumerate(PACKETS):
            w.write(T0 + i, p, linktype=LINKTYPE_ETHERNET if i != 1 else LINKTYPE_RAW)
    content = buf.getvalue()
    ends, pos = [], 0
    while pos < len(content):  # every block boundary is a clean place to cut
        pos += struct.unpack_from("<I", content, pos + 4)[0]
        ends.append(pos)
    return content, ends


def _tlog() -> tuple[bytes, list[int]]:
    out = tlog_spaced(FRAMES, int(T0 * 1e6), 1000)
    ends = list(itertools.accumulate(8 + len(f) for f in FRAMES))  # each entry: 8-byte time, then its frame
    return out, ends


CAPTURES = {"pcap": _pcap(), "pcapng": _pcapng(), "tlog": _tlog()}
MIN_DETECTABLE = {"pcap": 4, "pcapng": 12, "tlog": len(FRAMES[0]) + 8}


def read(content: bytes) -> tuple[str, list[Record], int, int]:
    """(kind, records, final position, size) of `content` read back from a file; exceptions propagate."""
    fd, path = tempfile.mkstemp(suffix=".cap")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(content)
        with open_capture(path) as r:
            recs = list(r)
            return r.kind, recs, r.position, r.size
    finally:
        os.unlink(path)


def decap_all(records: list[Record]) -> list[Payload]:
    d = Decapsulator()
    out = [p for rec in records for p in d.feed(rec)] + d.flush()
    assert all(isinstance(p, Payload) for p in out)
    assert all(n.code in CODES for p in out for n in p.notes)
    notes_in = sum(len(r.notes) for r in records)
    assert sum(len(p.notes) for p in out) >= notes_in  # record notes are never dropped
    return out


def test_truncation_at_every_byte() -> None:
    for kind, (content, ends) in CAPTURES.items():
        for cut in range(len(content)):
            got, recs, position, size = read(content[:cut])
            assert position == size
            if cut < MIN_DETECTABLE[kind]:
                continue
            assert got == kind, (kind, cut)
            notes = [n.code for r in recs for n in r.notes]
            if cut in ends:  # a clean cut between records or blocks
                assert not notes, (kind, cut, notes)
                continue
            assert notes, (kind, cut)
            decap_all(recs)


@FUZZ
@given(which=st.sampled_from(sorted(CAPTURES)), flips=st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 7)),
                                                                 min_size=1, max_size=6))
def test_bit_flips(which: str, flips: list[tuple[int, int]]) -> None:
    content = bytearray(CAPTURES[which][0])
    for pos, bit in flips:
        content[pos % len(content)] ^= 1 << bit
    kind, recs, position, size = read(bytes(content))
    assert position == size
    assert all(isinstance(r, Record) and isinstance(r.data, bytes) for r in recs)
    assert all(n.code in CODES for r in recs for n in r.notes)
    decap_all(recs)


@FUZZ
@given(index=st.integers(0, 2), length=st.one_of(st.integers(262145, 2**32 - 1), st.integers(0, 2**32 - 1)))
def test_absurd_pcap_lengths(index: int, length: int) -> None:
    content, ends = CAPTURES["pcap"]
    buf = bytearray(content)
    at = ends[index]
    real = struct.unpack_from("<I", buf, at + 8)[0]
    struct.pack_into("<I", buf, at + 8, length)
    _, recs, _, _ = read(bytes(buf))
    notes = [n.code for r in recs for n in r.notes]
    if length != real:
        assert notes, (index, length)  # truncated, snapped or skipped: something is said
    decap_all(recs)


@FUZZ
@given(index=st.integers(0, 2), length=st.integers(0, 2**32 - 1))
def test_absurd_pcapng_block_lengths(index: int, length: int) -> None:
    content, ends = CAPTURES["pcapng"]
    buf = bytearray(content)
    starts = [0] + ends[:-1]
    packet_blocks = [p for p in starts if struct.unpack_from("<I", content, p)[0] == 6]
    start = packet_blocks[index]
    real = struct.unpack_from("<I", buf, start + 4)[0]
    struct.pack_into("<I", buf, start + 4, length)
    _, recs, _, _ = read(bytes(buf))
    if length != real:
        assert [n for r in recs for n in r.notes], (index, length)
    decap_all(recs)


@FUZZ
@given(linktype=st.sampled_from([LINKTYPE_ETHERNET, LINKTYPE_RAW, LINKTYPE_NULL, LINKTYPE_LINUX_SLL,
                                 LINKTYPE_LINUX_SLL2, 0x71, 12345]),
       data=st.binary(max_size=120))
def test_decapsulator_random_packets(linktype: int, data: bytes) -> None:
    decap_all([Record(1, None, linktype, data, 0, len(data))])


@FUZZ
@given(flips=st.lists(st.tuples(st.integers(0, 200), st.integers(0, 7)), min_size=1, max_size=4),
       cut=st.integers(0, 200))
def test_decapsulator_mutated_tcp_and_udp(flips: list[tuple[int, int]], cut: int) -> None:
    from scapy.layers.inet import IP, TCP
    from scapy.layers.l2 import Ether

    tcp = bytes(Ether() / IP(src="1.2.3.4", dst="5.6.7.8") / TCP(sport=5760, dport=4000, seq=2**32 - 2) / FRAMES[0])
    records = []
    for i, base in enumerate((tcp, PACKETS[0], tcp)):
        buf = bytearray(base)
        for pos, bit in flips:
            buf[pos % len(buf)] ^= 1 << bit
        records.append(Record(i + 1, None, LINKTYPE_ETHERNET, bytes(buf[:cut]) if i == 2 else bytes(buf), 0, 0))
    decap_all(records)
