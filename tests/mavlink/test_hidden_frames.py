"""Frames MAVLink's C library reads where mavscope's framer shows other bytes (mavscope.mavlink.hidden).

The expected answers come from MAVLink's own C parser, compiled from pymavlink's headers and fed each
datagram byte by byte (tests/support/cparser.py), and from pymavlink's Python parser for what a
length-based reader shows. The frames are built by pymavlink; the crafted outer frames' bytes and CRCs
are written here by hand (header layout from DOMAIN.md, CRC-16/MCRF4XX over header and payload, then
the message's CRC_EXTRA from pymavlink).
"""

from __future__ import annotations

import struct

import pytest
from fastcrc import crc16
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import all as mavlink

from mavscope.capture.base import LINKTYPE_MAVLINK_RAW, LINKTYPE_MAVLINK_TLOG, Record
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.pipeline.dissect import Dissector
from tests.support import pmav
from tests.support.builders import mixed_frames
from tests.support.cparser import CParser, require_c_parser

ENCAPSULATED_DATA = 131  # 255-byte payload: room for a whole frame
STATUSTEXT = 253  # its id's low byte is 0xFD: an STX inside the header


@pytest.fixture(scope="module")
def cparser() -> CParser:
    return require_c_parser()


def frame_v2(msgid: int, payload: bytes, iflags: int = 0, seq: int = 7, sysid: int = 1, compid: int = 1,
             good_crc: bool = True) -> bytes:
    """A v2 frame written by hand: any incompat flags, CRC with the message's CRC_EXTRA (or spoiled)."""
    # not tests/native/build.frame_v2: the signed flag here comes without a signature, on purpose
    hdr = bytes([0xFD, len(payload), iflags, 0, seq, sysid, compid]) + msgid.to_bytes(3, "little")
    extra = mavlink.mavlink_map[msgid].crc_extra
    crc = crc16.mcrf4xx(bytes([extra]), crc16.mcrf4xx(hdr[1:] + payload))
    return hdr + payload + struct.pack("<H", crc if good_crc else crc ^ 0x5A5A)


def arm() -> bytes:
    """COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM (400), param1 1, from 255/190 to 1/1 (pymavlink)."""
    g = pmav.mav2(255, 190)
    g.seq = 40
    return g.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(g)


def carrier(inner: bytes, iflags: int = 0x02, lead: bytes = b"\x00\x00") -> bytes:
    """ENCAPSULATED_DATA (seqnr, then data) from 1/1 whose data holds `inner`."""
    payload = lead + inner
    return frame_v2(ENCAPSULATED_DATA, payload + bytes(255 - len(payload)), iflags)


def dissect(dialect: Dialect, datagrams: list[bytes]) -> list[Frame]:
    """Each datagram as a tlog entry (offset 0 each: positions are within the entry)."""
    items = Dissector(dialect).run([Record(i + 1, float(i + 1), LINKTYPE_MAVLINK_TLOG, d, 0, len(d))
                                    for i, d in enumerate(datagrams)])
    return [i for i in items if isinstance(i, Frame)]


def hidden(frames: list[Frame]) -> list[Frame]:
    return [f for f in frames if any(n.code == "hidden-frame" for n in f.notes)]


def pymavlink_reads(data: bytes) -> list[str]:
    """What pymavlink's Python parser (robust parsing, as MAVProxy) makes of the bytes."""
    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    return [m.get_type() for m in mav.parse_buffer(data) or []]


def test_a_command_inside_a_frame_with_an_unknown_flag(dialect: Dialect, cparser: CParser) -> None:
    inner = arm()
    data = carrier(inner)
    assert cparser.frames_of(data) == {(12, len(inner))}  # the vehicle reads the ARM command
    assert pymavlink_reads(data) == ["BAD_DATA"]  # a length-based reader shows the outer frame only
    frames = dissect(dialect, [data])
    assert [(f.offset, len(f.raw), f.msgname) for f in frames] == [(0, len(data), "ENCAPSULATED_DATA"),
                                                                    (12, len(inner), "COMMAND_LONG")]
    (h,) = hidden(frames)
    assert h.raw == inner and h.crc_status is CrcStatus.OK and (h.sysid, h.compid, h.seq) == (255, 190, 40)
    (n,) = [n for n in h.notes if n.code == "hidden-frame"]
    assert "12 bytes before" in n.message and "0x02" in n.message


def test_an_stx_in_the_outer_header_swallows_the_inner_frame(dialect: Dialect, cparser: CParser) -> None:
    # STATUSTEXT's id byte is 0xFD: the C library starts a frame there and reads over the inner one
    inner = arm()
    payload = bytes([6]) + inner
    data = frame_v2(STATUSTEXT, payload + bytes(51 - len(payload)), 0x02)
    assert cparser.frames_of(data) == set()
    assert hidden(dissect(dialect, [data])) == []


def test_nested_and_straddling(dialect: Dialect, cparser: CParser) -> None:
    inner = arm()
    middle = frame_v2(ENCAPSULATED_DATA, (b"\x00\x00" + inner).ljust(255, b"\x00"), 0x04)
    nested = carrier(middle[:200], lead=b"\x00")  # the outer holds the middle's first 200 bytes
    rest = middle[200:]
    data = nested + rest  # the middle frame runs on past the outer's end
    expect = cparser.frames_of(data)
    assert expect == {(11 + 12, len(inner))}
    frames = dissect(dialect, [data])
    assert {(f.offset, len(f.raw)) for f in hidden(frames)} == expect
    # straddling: the inner frame starts in the outer's last bytes and ends in the bytes after it
    body = bytearray(255)
    tail_in = 20  # bytes of the inner frame inside the outer payload
    body[255 - tail_in:] = inner[:tail_in]
    data = frame_v2(ENCAPSULATED_DATA, bytes(body), 0x02) + inner[tail_in:]
    # the outer's CRC lies between the inner's bytes: the inner frame as the C library reads it is
    # inner[:20] + CRC + inner[20:-2]..., whose CRC fails. So nothing is read, and nothing is claimed.
    assert cparser.frames_of(data) == set()
    assert hidden(dissect(dialect, [data])) == []


def test_a_damaged_frame_read_whole_hides_a_frame_the_framer_resynchronised_past(
        dialect: Dialect, cparser: CParser) -> None:
    # A bad-CRC frame whose length covers a CRC-valid frame F' (found by the framer's resynchronisation),
    # and F' holds, past the bad frame's end, a frame V that the C library (and pymavlink) read.
    v = arm()
    f_payload = bytearray(255)
    f_payload[100 : 100 + len(v)] = v
    f_prime = frame_v2(ENCAPSULATED_DATA, bytes(f_payload), 0, seq=9)
    # The bad frame (only its header is written: 20 bytes of its own before F') ends 5 zero bytes before V:
    # had it ended at V, the framer would have taken it whole too (a damaged frame that ends where a valid
    # one starts), as the C library does.
    bad_len = 20 + 10 + 100 - 5 - 12
    bad = frame_v2(ENCAPSULATED_DATA, bytes(bad_len), 0, seq=1, good_crc=False)[:10]
    data = bad + bytes(10) + f_prime
    assert data[130 : 130 + len(v)] == v
    expect = cparser.frames_of(data)
    assert expect == {(130, len(v))}
    frames = dissect(dialect, [data])
    assert any(f.offset == 20 and f.msgname == "ENCAPSULATED_DATA" for f in frames)  # F', resynchronised
    assert {(f.offset, len(f.raw)) for f in hidden(frames)} == expect


def test_a_damaged_frame_ending_in_fd_starts_the_next_one(dialect: Dialect, cparser: CParser) -> None:
    inner = arm()
    for crc_hi in range(256):  # a bad frame whose last byte is 0xFD: find a payload byte giving that
        bad = bytearray(frame_v2(0, bytes([crc_hi]) + bytes(8), 0, good_crc=False))
        if bad[-1] == 0xFD:
            break
    else:
        pytest.fail("no payload gives a CRC ending in 0xFD")
    data = carrier(bytes(bad[:-1]) + inner)  # the bad frame's last byte is the inner frame's STX
    # mavlink_parse_char (PX4, QGroundControl) starts a frame at that byte; mavlink_frame_char_buffer
    # (ArduPilot) does not
    expect = cparser.frames_of(data, "parse")
    assert expect == {(12 + len(bad) - 1, len(inner))} and cparser.frames_of(data, "frame") == set()
    (h,) = hidden(dissect(dialect, [data]))
    assert {(h.offset, len(h.raw))} == expect
    (n,) = [n for n in h.notes if n.code == "hidden-frame"]
    assert n.message.startswith("PX4 and QGroundControl (mavlink_parse_char) reads this frame")


def test_a_signed_damaged_frame_ends_at_its_crc_for_px4_and_at_its_signature_for_ardupilot(
        dialect: Dialect, cparser: CParser) -> None:
    # A signed frame with a bad CRC, inside a carrier: its 13 signature bytes hold the start of a frame.
    # mavlink_parse_char reads the signature bytes afresh; mavlink_frame_char_buffer skips them.
    inner = arm()
    bad = frame_v2(0, bytes(9), 0x01, good_crc=False)  # header says signed: 13 signature bytes follow
    data = carrier(bad + inner)  # the inner frame starts where the signature would
    parse, frame = cparser.frames_of(data, "parse"), cparser.frames_of(data, "frame")
    assert parse == {(12 + len(bad), len(inner))} and frame == set()
    assert {(f.offset, len(f.raw)) for f in hidden(dissect(dialect, [data]))} == parse


def test_the_audit_and_stats_report_it(cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from scapy.all import IP, UDP, Ether, wrpcap

    v = pmav.mav2()
    pk = [Ether() / IP(src="10.0.0.2", dst="10.0.0.1") / UDP(sport=14550, dport=14555) / pmav.heartbeat(v),
          Ether() / IP(src="10.0.0.3", dst="10.0.0.1") / UDP(sport=14550, dport=14555) / carrier(arm())]
    for i, p in enumerate(pk):
        p.time = 1.0 + i
    path = tmp_path / "hidden.pcap"
    wrpcap(str(path), pk)
    status, out, _ = cli("audit", path)
    assert status == 1 and "hidden-frame" in out and "(frames 2)" in out
    for engine in ("", "1"):
        doc = cli.json("stats", path, environ={"MAVSCOPE_PURE": engine})
        (f,) = [f for f in doc["findings"] if f["code"] == "hidden-frame"]
        assert f["frames"] == [2] and "1 COMMAND_LONG from 255/190" in f["message"]
    rows = cli.jsonl(path, "-Y", "note.hidden-frame")
    assert [(r["sysid"], r["msgname"]) for r in rows] == [(255, "COMMAND_LONG")]
    status, out, _ = cli("read", path)
    assert "[hidden: MAVLink's C library reads it]" in out


def _sessions() -> list[bytes]:
    """Frames to mutate: a vehicle's, a ground station's, a signed one, v1, and carriers holding frames."""
    parts = mixed_frames()
    parts.append(carrier(arm()))
    parts.append(carrier(pmav.heartbeat(pmav.mav2()) + arm(), 0x80))
    return parts


PARTS = _sessions()


@st.composite
def datagrams(draw: st.DrawFn) -> bytes:
    data = bytearray(b"".join(draw(st.lists(st.sampled_from(PARTS), min_size=1, max_size=5))))
    for _ in range(draw(st.integers(0, 6))):
        pos = draw(st.integers(0, len(data) - 1))
        kind = draw(st.sampled_from(["flip", "cut", "insert", "flags", "stx"]))
        if kind == "flip":
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif kind == "cut":
            del data[pos : pos + draw(st.integers(1, 40))]
        elif kind == "insert":
            data[pos:pos] = draw(st.sampled_from([arm(), b"\xfd", b"\xfe", bytes(7)]))
        elif kind == "flags":
            at = data.find(b"\xfd", pos)
            if 0 <= at < len(data) - 2:
                data[at + 2] |= draw(st.sampled_from([0x02, 0x04, 0x40]))
        else:
            data[pos] = 0xFD
        if not data:
            data = bytearray(b"\xfd")
    return bytes(data)


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(batch=st.lists(datagrams(), min_size=1, max_size=8))
def test_every_frame_the_c_library_reads_is_shown(dialect: Dialect, cparser: CParser, batch: list[bytes]) -> None:
    """Per datagram: every frame the C library reads is a frame mavscope shows with a good CRC, and every
    frame mavscope calls hidden is one the C library reads."""
    expect = cparser.frames(batch)  # through either entry point
    for data, reads in zip(batch, expect, strict=True):
        frames = dissect(dialect, [data])
        shown = {(f.offset, len(f.raw)) for f in frames if f.crc_status is CrcStatus.OK}
        assert reads <= shown, (data.hex(), reads - shown)
        assert {(f.offset, len(f.raw)) for f in hidden(frames)} <= reads


@settings(max_examples=200, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.lists(datagrams(), min_size=1, max_size=3).map(b"".join),
       chunks=st.lists(st.integers(1, 97), min_size=1))
def test_a_stream_shows_what_the_c_library_reads(dialect: Dialect, cparser: CParser, data: bytes,
                                                 chunks: list[int]) -> None:
    """A raw stream, which the C library reads as one run of bytes, given whole or in pieces of any sizes
    (a TCP sender chooses them): every frame it reads is one mavscope shows with a good CRC, every frame
    called hidden is one it reads, and no frame comes twice."""
    reads = cparser.frames_of(data)
    for sizes in ([len(data)], chunks):
        records, off = [], 0
        while off < len(data):
            size = sizes[len(records) % len(sizes)]
            records.append(Record(len(records) + 1, None, LINKTYPE_MAVLINK_RAW, data[off : off + size], off,
                                  len(data[off : off + size])))
            off += size
        frames = [i for i in Dissector(dialect).run(records) if isinstance(i, Frame)]
        shown = {(f.offset, len(f.raw)) for f in frames if f.crc_status is CrcStatus.OK}
        assert reads <= shown, (data.hex(), sizes, reads - shown)
        assert {(f.offset, len(f.raw)) for f in hidden(frames)} <= reads, (data.hex(), sizes)
        assert len({(f.offset, len(f.raw)) for f in frames}) == len(frames)


def raw_stream(dialect: Dialect, data: bytes, size: int) -> list[Frame]:
    """`data` as a raw stream read in pieces of `size` bytes."""
    records = [Record(i + 1, None, LINKTYPE_MAVLINK_RAW, data[off : off + size], off, len(data[off : off + size]))
               for i, off in enumerate(range(0, len(data), size))]
    return [i for i in Dissector(dialect).run(records) if isinstance(i, Frame)]


@pytest.mark.parametrize("size", [1, 5, 40, 400])
def test_a_walk_goes_on_across_the_pieces_of_a_stream(dialect: Dialect, cparser: CParser, size: int) -> None:
    """A heartbeat whose LEN byte grew by 2, then the ARM carrier: the C library reads the ARM command, from
    the whole stream. In pieces of 1, 5 or 40 bytes the walk from the damaged heartbeat needs bytes of the
    next piece; it used to stop for good there (and missed the ARM), now it goes on from where it stopped."""
    hb = pmav.heartbeat(pmav.mav2())
    data = hb[:1] + bytes([hb[1] + 2]) + hb[2:] + carrier(arm())
    at = data.index(arm())
    assert (at, len(arm())) in cparser.frames_of(data)
    frames = raw_stream(dialect, data, size)
    assert [(f.offset, f.raw) for f in hidden(frames)] == [(at, arm())]
    assert [(f.offset, f.msgname, f.crc_status) for f in frames] == [
        (len(hb), "ENCAPSULATED_DATA", CrcStatus.OK), (at, "COMMAND_LONG", CrcStatus.OK)]  # the heartbeat: skipped


class _Counted:
    """Framer.candidate, counting its calls and the bytes its CRC may cover."""

    def __init__(self, candidate) -> None:  # type: ignore[no-untyped-def]
        self.candidate, self.work = candidate, 0

    def __call__(self, buf: bytes, pos: int, end: int):  # type: ignore[no-untyped-def]
        self.work += 1 + min(280, end - pos)
        return self.candidate(buf, pos, end)


HOSTILE = {
    "carriers": lambda n: (carrier(arm()) + carrier(arm(), 0x04)) * (n // 534),
    "fd-fe": lambda n: b"\xfd\xfe" * (n // 2),
    "dropped-headers": lambda n: b"\xfd\x05\x02" * (n // 3),  # every STX a frame dropped at its flags
    "signed-bad": lambda n: (frame_v2(0, bytes(9), 0x01, good_crc=False) + b"\xfd") * (n // 22),
}


@pytest.mark.parametrize("chunk", [None, 1, 100])
@pytest.mark.parametrize("pattern", HOSTILE)
def test_the_walk_is_linear(dialect: Dialect, pattern: str, chunk: int | None) -> None:
    """Counted, never timed: the candidate checks (with their CRC bytes) per byte stay flat, for a datagram
    (chunk None: the walks alone) and for a stream fed in pieces (the framer's and the carried walks')."""
    from mavscope.mavlink.framing import Framer, StreamFramer
    from mavscope.mavlink.hidden import hidden_frames

    framer = Framer(dialect.messages)
    per_byte = []
    for n in (4_096, 32_768) if chunk == 1 else (8_192, 65_536):
        data = HOSTILE[pattern](n)
        counted = _Counted(framer.candidate)
        if chunk is None:
            found, skipped, _ = framer.scan(data, 0, len(data), True)
            hidden_frames(counted, data, found, skipped, len(data), len(data))
        else:
            framer.candidate = counted  # type: ignore[method-assign]  # the scan's and the walks' checks
            sf = StreamFramer(framer, ("raw",))
            for i in range(0, len(data), chunk):
                sf.feed(data[i : i + chunk], i // chunk + 1, i)
                sf.take(False)
            sf.take(True)
            del framer.candidate
        per_byte.append(counted.work / len(data))
    assert per_byte[1] <= 1.1 * per_byte[0] + 0.01 and per_byte[1] <= (600 if chunk is None else 2000), per_byte
