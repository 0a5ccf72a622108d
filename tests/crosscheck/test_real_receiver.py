"""On the real captures: every frame MAVLink's C library reads is a frame mavscope shows.

The expected side is the C library itself (tests/support/cparser.py: pymavlink's mavlink_helpers.h, through
both entry points, mavlink_parse_char and mavlink_frame_char_buffer), fed what a receiver gets: each UDP
datagram of the pcaps as scapy extracts it, and each raw serial dump whole. mavscope must show each frame
it reads with a good CRC at the same place, and call hidden only frames it reads. The tlogs are left out:
a tlog entry has no length of its own, so its bytes are the frame the logger's own parser read.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import pytest

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from tests.support.cparser import CParser, require_c_parser
from tests.support.ftpflows import frames_of

PCAPS = ("ap_sitl_attack1_signed_knownkey.pcap", "ipal_transcriber_MAVLink.pcap")
RAW = ("gomavlib_signed_testvectors_key4F_DERIVED.raw", "px4_fw_mission_download_raw.bin")


@pytest.fixture(scope="module")
def cparser() -> CParser:
    return require_c_parser()


def _frames(path: Path, dialect: Dialect) -> list[Frame]:
    return frames_of(path, dialect)


@pytest.mark.parametrize("name", PCAPS)
def test_udp_datagrams(real_captures: Path, dialect: Dialect, cparser: CParser, name: str) -> None:
    from scapy.all import UDP, PcapReader

    with PcapReader(str(real_captures / name)) as r:
        datagrams = [(n, bytes(p[UDP].payload)) for n, p in enumerate(r, 1) if UDP in p]
    reads = cparser.frames([d for _, d in datagrams])
    shown: dict[int, set[bytes]] = defaultdict(set)
    hidden: dict[int, set[bytes]] = defaultdict(set)
    for f in _frames(real_captures / name, dialect):
        if f.crc_status is CrcStatus.OK:
            shown[f.record].add(f.raw)
        if any(n.code == "hidden-frame" for n in f.notes):
            hidden[f.record].add(f.raw)
    total = 0
    for (record, data), got in zip(datagrams, reads, strict=True):
        raws = {data[s : s + n] for s, n in got}
        total += len(raws)
        assert raws <= shown[record], record
        assert hidden[record] <= raws, record
    assert total >= len(datagrams) > 0  # a frame or more a datagram: the comparison is not empty


@pytest.mark.parametrize("name", RAW)
def test_raw_streams(real_captures: Path, dialect: Dialect, cparser: CParser, name: str) -> None:
    data = (real_captures / name).read_bytes()
    reads = cparser.frames_of(data)
    frames = _frames(real_captures / name, dialect)
    shown = {(f.offset, len(f.raw)) for f in frames if f.crc_status is CrcStatus.OK}
    assert reads and reads <= shown
    assert {(f.offset, len(f.raw)) for f in frames if any(n.code == "hidden-frame" for n in f.notes)} <= reads
