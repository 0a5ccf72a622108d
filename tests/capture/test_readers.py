"""Capture readers: format detection, pcap/pcapng/tlog/raw decoding, damaged files, the real tlogs."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from mavscope.capture.base import (
    LINKTYPE_ETHERNET,
    LINKTYPE_LINUX_SLL,
    LINKTYPE_MAVLINK_RAW,
    LINKTYPE_MAVLINK_TLOG,
    LINKTYPE_RAW,
)
from mavscope.capture.detect import detect_kind, open_capture
from mavscope.capture.raw import CHUNK
from mavscope.errors import CaptureError
from tests.support.builders import pcapng_block, pcapng_epb, pcapng_idb, pcapng_shb, tlog_spaced

T0 = 1_700_000_000
T0_US = T0 * 1_000_000  # the tlogs' first entry (tlog_spaced: entries 1 ms apart)


def pcap_bytes(records: list[tuple[int, int, bytes, int]], endian: str = "<", ns: bool = False,
               linktype: int = LINKTYPE_ETHERNET, snaplen: int = 65535) -> bytes:
    """A pcap file of (seconds, fraction, data, orig_len) records."""
    # not tests/native/build.pcap: each record's original length is chosen here (the readers' cut records)
    magic = 0xA1B23C4D if ns else 0xA1B2C3D4
    out = [struct.pack(endian + "IHHiIII", magic, 2, 4, 0, 0, snaplen, linktype)]
    for sec, frac, data, orig in records:
        out.append(struct.pack(endian + "IIII", sec, frac, len(data), orig) + data)
    return b"".join(out)


def v2_frame(seq: int, payload: bytes = b"\x01\x02\x03", signed: bool = False) -> bytes:
    """A v2 frame by layout only (the CRC is not checked here)."""
    flags = 1 if signed else 0
    frame = bytes([0xFD, len(payload), flags, 0, seq, 1, 1, 0, 0, 0]) + payload + b"\xaa\xbb"
    return frame + (bytes(13) if signed else b"")


def write(tmp_path: Path, name: str, content: bytes) -> Path:
    p = tmp_path / name
    p.write_bytes(content)
    return p


def read_all(path: Path) -> list:
    with open_capture(path) as r:
        return list(r)


# ---- detection and opening -----------------------------------------------------------------------------


@pytest.mark.parametrize("endian", ["<", ">"])
@pytest.mark.parametrize("ns", [False, True])
def test_pcap_both_byte_orders_and_resolutions(tmp_path: Path, endian: str, ns: bool) -> None:
    frac = 123_456_789 if ns else 123_456
    content = pcap_bytes([(T0, frac, b"abc", 3), (T0 + 1, 0, b"hello", 5)], endian, ns)
    path = write(tmp_path, "x.bin", content)  # the extension does not matter
    with open_capture(path) as r:
        assert r.kind == "pcap" and r.size == len(content)
        recs = list(r)
        assert r.position == r.size
    assert [rec.data for rec in recs] == [b"abc", b"hello"]
    assert recs[0].time == pytest.approx(T0 + (0.123456789 if ns else 0.123456), abs=1e-7)
    assert recs[0].offset == 24 + 16 and recs[0].number == 1 and recs[1].number == 2
    assert all(rec.linktype == LINKTYPE_ETHERNET and not rec.notes for rec in recs)


def test_detection_ignores_extension(tmp_path: Path) -> None:
    assert detect_kind(write(tmp_path, "a.pcapng", pcap_bytes([]))) == "pcap"
    assert detect_kind(write(tmp_path, "b.pcap", pcapng_shb() + pcapng_idb(1))) == "pcapng"
    assert detect_kind(write(tmp_path, "c.pcap", tlog_spaced([v2_frame(0), v2_frame(1)], T0_US))) == "tlog"
    assert detect_kind(write(tmp_path, "d.tlog", b"\xfd\x09hello, not a tlog")) == "raw"


def test_missing_directory_and_empty(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match="no such file"):
        open_capture(tmp_path / "nope.pcap")
    with pytest.raises(CaptureError, match="directory"):
        open_capture(tmp_path)
    empty = write(tmp_path, "empty.pcap", b"")
    with open_capture(empty) as r:
        assert r.kind == "raw" and r.size == 0 and list(r) == []


def test_unreadable_file(tmp_path: Path) -> None:
    import os

    p = write(tmp_path, "locked.pcap", pcap_bytes([]))
    p.chmod(0)
    try:
        if os.access(p, os.R_OK):
            pytest.skip("running as a user who can read any file")
        with pytest.raises(CaptureError, match="permission"):
            open_capture(p)
    finally:
        p.chmod(0o644)


# ---- pcap anomalies ------------------------------------------------------------------------------------


def test_pcap_snapped_record_noted(tmp_path: Path) -> None:
    recs = read_all(write(tmp_path, "s.pcap", pcap_bytes([(T0, 0, b"abcd", 100)])))
    assert recs[0].orig_len == 100 and [n.code for n in recs[0].notes] == ["record-snapped"]


def test_pcap_truncated_last_record(tmp_path: Path) -> None:
    content = pcap_bytes([(T0, 0, b"first", 5), (T0, 1, b"0123456789", 10)])[:-4]
    recs = read_all(write(tmp_path, "t.pcap", content))
    assert recs[1].data == b"012345" and recs[1].notes[0].code == "record-truncated"
    assert recs[1].notes[0].offset == 24 + 16 + 5


def test_pcap_cut_inside_header(tmp_path: Path) -> None:
    content = pcap_bytes([(T0, 0, b"first", 5), (T0, 1, b"x", 1)])
    recs = read_all(write(tmp_path, "h.pcap", content[:24 + 21 + 7]))
    assert recs[0].data == b"first" and recs[-1].data == b"" and recs[-1].notes[0].code == "record-truncated"


def test_pcap_resync_after_absurd_header(tmp_path: Path) -> None:
    good = [(T0 + i, i, bytes([i]) * 20, 20) for i in range(5)]
    content = bytearray(pcap_bytes(good))
    bad_at = 24 + 2 * 36
    struct.pack_into("<I", content, bad_at + 8, 0x7FFFFFFF)  # absurd incl_len of record 3
    recs = read_all(write(tmp_path, "r.pcap", bytes(content)))
    assert [r.data[0] for r in recs] == [0, 1, 3, 4]
    garbage = recs[2].notes[0]
    assert garbage.code == "capture-garbage" and garbage.offset == bad_at and "36 bytes skipped" in garbage.message


def test_pcap_garbage_to_the_end_keeps_the_note(tmp_path: Path) -> None:
    content = pcap_bytes([(T0, 0, b"ok", 2)]) + struct.pack("<IIII", T0, 0, 0x7FFFFFFF, 5) + b"\xff" * 40
    recs = read_all(write(tmp_path, "g.pcap", content))
    assert recs[0].data == b"ok"
    assert recs[-1].data == b"" and recs[-1].notes[0].code == "capture-garbage"


def test_pcap_short_file_header(tmp_path: Path) -> None:
    recs = read_all(write(tmp_path, "short.pcap", pcap_bytes([])[:10]))
    assert len(recs) == 1 and recs[0].notes[0].code == "record-truncated"


# ---- pcapng --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("e", ["<", ">"])
def test_pcapng_two_interfaces_different_linktypes_and_resolutions(tmp_path: Path, e: str) -> None:
    content = (pcapng_shb(e) + pcapng_idb(LINKTYPE_ETHERNET, e=e) + pcapng_idb(LINKTYPE_RAW, tsresol=9, e=e)
               + pcapng_idb(LINKTYPE_LINUX_SLL, tsresol=0x80 | 10, tsoffset=1000, e=e)
               + pcapng_epb(0, T0 * 10**6 + 250_000, b"eth", e=e) + pcapng_epb(1, T0 * 10**9 + 1, b"raw!", e=e)
               + pcapng_epb(2, 5 * 1024 + 512, b"sll", e=e) + pcapng_block(5, b"\0" * 20, e))  # an ISB is skipped
    recs = read_all(write(tmp_path, "two.pcapng", content))
    assert [(r.linktype, r.data) for r in recs] == [(1, b"eth"), (101, b"raw!"), (113, b"sll")]
    assert recs[0].time == pytest.approx(T0 + 0.25)
    assert recs[1].time == pytest.approx(T0 + 1e-9, abs=1e-6)
    assert recs[2].time == pytest.approx(1000 + 5.5)
    idbs = len(pcapng_idb(1, e=e)) + len(pcapng_idb(101, 9, e=e)) + len(pcapng_idb(113, 0x8A, 1000, e=e))
    assert recs[0].offset == len(pcapng_shb(e)) + idbs + 28


def test_pcapng_sections_reset_interfaces_and_byte_order(tmp_path: Path) -> None:
    content = (pcapng_shb("<") + pcapng_idb(LINKTYPE_ETHERNET) + pcapng_epb(0, 1, b"a")
               + pcapng_shb(">") + pcapng_idb(LINKTYPE_RAW, e=">") + pcapng_epb(0, 2, b"b", e=">"))
    recs = read_all(write(tmp_path, "sec.pcapng", content))
    assert [(r.linktype, r.data) for r in recs] == [(1, b"a"), (101, b"b")]


def test_pcapng_simple_and_obsolete_packet_blocks(tmp_path: Path) -> None:
    spb = pcapng_block(3, struct.pack("<I", 10) + b"0123456789")
    opb = pcapng_block(2, struct.pack("<HHIIII", 0, 0, 0, 7_000_000, 3, 3) + b"opb")
    recs = read_all(write(tmp_path, "spb.pcapng", pcapng_shb() + pcapng_idb(LINKTYPE_ETHERNET) + spb + opb))
    assert recs[0].data == b"0123456789" and recs[0].time is None and recs[0].orig_len == 10
    assert recs[1].data == b"opb" and recs[1].time == pytest.approx(7.0)


def test_pcapng_snapped_and_truncated(tmp_path: Path) -> None:
    content = pcapng_shb() + pcapng_idb(1) + pcapng_epb(0, 1, b"abcd", orig=60) + pcapng_epb(0, 2, b"0123456789")
    recs = read_all(write(tmp_path, "cut.pcapng", content[:-10]))
    assert recs[0].notes[0].code == "record-snapped"
    assert recs[1].notes[-1].code == "record-truncated" and recs[1].data.startswith(b"01234")


def test_pcapng_corrupt_block_length_resyncs(tmp_path: Path) -> None:
    blocks = [pcapng_shb(), pcapng_idb(1), pcapng_epb(0, 1, b"one"), pcapng_epb(0, 2, b"two"),
              pcapng_epb(0, 3, b"three")]
    content = bytearray(b"".join(blocks))
    at = len(blocks[0]) + len(blocks[1]) + len(blocks[2])
    struct.pack_into("<I", content, at + 4, 0x00FFFFF0)
    recs = read_all(write(tmp_path, "bad.pcapng", bytes(content)))
    assert [r.data for r in recs] == [b"one", b"three"]
    assert recs[1].notes[0].code == "capture-garbage" and recs[1].notes[0].offset == at


def test_pcapng_undefined_interface(tmp_path: Path) -> None:
    content = pcapng_shb() + pcapng_idb(1) + pcapng_epb(3, 1, b"x") + pcapng_epb(0, 1, b"y")
    recs = read_all(write(tmp_path, "noif.pcapng", content))
    assert [r.data for r in recs] == [b"y"] and recs[0].notes[0].code == "capture-garbage"


# ---- tlog and raw --------------------------------------------------------------------------------------


def test_tlog_entries_v1_v2_signed(tmp_path: Path) -> None:
    v1 = bytes([0xFE, 2, 7, 1, 1, 0, 9, 9, 0xAA, 0xBB])
    frames = [v2_frame(0), v1, v2_frame(1, b"\xfd" * 5, signed=True)]
    recs = read_all(write(tmp_path, "x.tlog", tlog_spaced(frames, T0_US)))
    assert [r.data for r in recs] == frames
    assert all(r.linktype == LINKTYPE_MAVLINK_TLOG for r in recs)
    assert recs[1].time == pytest.approx(T0 + 0.001) and recs[0].offset == 8


def test_tlog_resync_and_truncation(tmp_path: Path) -> None:
    frames = [v2_frame(i) for i in range(4)]
    content = bytearray(tlog_spaced(frames, T0_US))
    entry = 8 + len(frames[0])
    content[entry + 8] = 0x00  # the second entry loses its STX
    content = bytes(content[:-3])  # and the last entry is cut
    recs = read_all(write(tmp_path, "r.tlog", content))
    # the second entry still has a plausible timestamp, and the third one starts where its frame ended: it is
    # an entry of bytes that are not MAVLink (as MAVProxy logs data it could not parse), delivered as it is
    assert [r.data for r in recs[:3]] == [frames[0], b"\x00" + frames[1][1:], frames[2]]
    assert not any(r.notes for r in recs[:3]) and recs[1].offset == entry + 8
    assert recs[3].data == frames[3][:-3] and recs[3].notes[0].code == "record-truncated"
    # a broken timestamp as well: no entry there, the bytes up to the next entry are skipped and noted
    broken = bytearray(content)
    broken[entry:entry + 2] = b"\xff\xff"
    recs = read_all(write(tmp_path, "b.tlog", bytes(broken)))
    assert [r.data for r in recs[:2]] == [frames[0], frames[2]]
    assert recs[1].notes[0].code == "capture-garbage" and recs[1].notes[0].offset == entry


def test_raw_chunks(tmp_path: Path) -> None:
    content = bytes(range(256)) * ((CHUNK * 2 + 1000) // 256)
    recs = read_all(write(tmp_path, "raw.bin", content))
    assert b"".join(r.data for r in recs) == content and len(recs) == 3
    assert all(r.time is None and r.linktype == LINKTYPE_MAVLINK_RAW for r in recs)
    assert recs[1].offset == CHUNK


# ---- the real telemetry logs ---------------------------------------------------------------------------


def _crc_valid(records: list) -> tuple[int, int]:
    from pymavlink.dialects.v20 import all as mavall

    mav = mavall.MAVLink(None)
    mav.robust_parsing = True
    v2 = v1 = 0
    for rec in records:
        for m in mav.parse_buffer(rec.data) or []:
            if not isinstance(m, mavall.MAVLink_bad_data):
                v2 += rec.data[0] == 0xFD
                v1 += rec.data[0] == 0xFE
    return v2, v1


@pytest.mark.parametrize(("name", "v2", "v1"), [
    ("ardusub_log_tools_small.tlog", 35_912, 0),
    ("bluerobotics_mavlink_server_blueos_00025.tlog", 30_437, 2),
])
def test_real_tlogs_frame_counts(real_captures: Path, name: str, v2: int, v1: int) -> None:
    with open_capture(real_captures / name) as r:
        assert r.kind == "tlog"
        records = list(r)
    assert not [n for rec in records for n in rec.notes]
    assert _crc_valid(records) == (v2, v1)


def test_a_file_name_with_a_nul_byte_is_a_capture_error() -> None:
    from mavscope.capture.reader import open_file
    from mavscope.errors import CaptureError

    with pytest.raises(CaptureError, match="not a usable file name"):
        open_file("/tmp/a\0b.pcap")
