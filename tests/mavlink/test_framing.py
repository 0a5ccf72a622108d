"""The framer: datagrams and streams, damaged input, resynchronisation without phantom frames."""

from __future__ import annotations

import random

import pytest

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, decode_payload
from mavscope.mavlink.framing import Framer, StreamFramer, build_frame
from tests.support import pmav


@pytest.fixture(scope="module")
def framer(dialect: Dialect) -> Framer:
    return Framer(dialect.messages)


def _frames(framer: Framer, data: bytes):
    found, skipped, end = framer.scan(data, 0, len(data), True)
    assert end == len(data)
    return found, skipped


def test_single_v2_frame(framer: Framer, dialect: Dialect) -> None:
    data = pmav.command_long_rtl(pmav.mav2(255, 190))
    found, skipped = _frames(framer, data)
    assert found == [(0, len(data), CrcStatus.OK, int.from_bytes(data[-2:], "little"))]
    assert skipped == []
    f = build_frame(data, 0, len(data), CrcStatus.OK, found[0][3], dialect.messages, 1, 1, None, "raw",
                    None, None, 0, (), None)
    assert (f.version, f.sysid, f.compid, f.msgid, f.msgname) == (2, 255, 190, 76, "COMMAND_LONG")
    fields = decode_payload(f)
    assert fields is not None and fields["command"] == 20 and fields["confirmation"] == 0


def test_v1_frame(framer: Framer, dialect: Dialect) -> None:
    mav = pmav.mav1(7, 1)
    data = mav.heartbeat_encode(2, 3, 81, 0, 4, 3).pack(mav)
    found, _ = _frames(framer, data)
    assert [(s, st) for _, s, st, _ in found] == [(len(data), CrcStatus.OK)]
    f = build_frame(data, 0, len(data), CrcStatus.OK, found[0][3], dialect.messages, 1, 1, None, "raw",
                    None, None, 0, (), None)
    assert (f.version, f.sysid, f.msgid) == (1, 7, 0)
    assert decode_payload(f)["autopilot"] == 3  # type: ignore[index]


def test_several_frames_garbage_bad_crc(framer: Framer) -> None:
    mav = pmav.mav2()
    a, b = pmav.heartbeat(mav), pmav.statustext(mav, "two")
    bad = bytearray(pmav.command_long_rtl(mav))
    bad[12] ^= 0x40
    data = b"\x00\xfd\x01junk" + a + bytes(bad) + b
    found, skipped = _frames(framer, data)
    assert [st for _, _, st, _ in found] == [CrcStatus.OK, CrcStatus.BAD, CrcStatus.OK]
    assert found[0][0] == 7 and skipped == [(0, 7)]


def test_bad_crc_last_frame_is_reported(framer: Framer) -> None:
    mav = pmav.mav2()
    bad = bytearray(pmav.heartbeat(mav))
    bad[-1] ^= 1
    found, _ = _frames(framer, pmav.statustext(mav) + bytes(bad))
    assert [st for _, _, st, _ in found] == [CrcStatus.OK, CrcStatus.BAD]


def test_stray_stx_bytes_are_not_frames(framer: Framer) -> None:
    mav = pmav.mav2()
    good = pmav.heartbeat(mav)
    stray = bytes([0xFD, 0x30, 0x00, 0xFE, 0x01, 0x02, 0x03, 0xFD, 0x10]) + b"abcdefgh"
    found, skipped = _frames(framer, stray + good + stray[:4] + good)
    assert [(pos, st) for pos, _, st, _ in found] == [(17, CrcStatus.OK), (17 + len(good) + 4, CrcStatus.OK)]
    assert skipped == [(0, 17), (17 + len(good), 4)]


def test_truncated_frame_at_end(framer: Framer) -> None:
    mav = pmav.mav2()
    a, b = pmav.heartbeat(mav), pmav.command_long_rtl(mav)
    found, _ = _frames(framer, a + b[:20])
    assert [(s, st) for _, s, st, _ in found] == [(len(a), CrcStatus.OK), (20, CrcStatus.TRUNCATED)]


def test_unknown_msgid_is_unchecked(framer: Framer) -> None:
    mav = pmav.mav2()
    frame = bytearray(pmav.heartbeat(mav))
    frame[7:10] = (16000000).to_bytes(3, "little")
    found, _ = _frames(framer, bytes(frame))
    assert [st for _, _, st, _ in found] == [CrcStatus.UNCHECKED]


def test_signed_frame_signature_block(framer: Framer, dialect: Dialect) -> None:
    mav = pmav.mav2()
    mav.signing.secret_key = bytes(range(32))
    mav.signing.link_id = 3
    mav.signing.timestamp = 123456789
    mav.signing.sign_outgoing = True
    data = pmav.heartbeat(mav)
    found, _ = _frames(framer, data)
    pos, size, st, crc = found[0]
    assert st is CrcStatus.OK and size == len(data)
    f = build_frame(data, pos, size, st, crc, dialect.messages, 1, 1, None, "raw", None, None, 0, (), None)
    assert f.signature is not None
    assert f.signature.link_id == 3 and f.signature.value == data[-6:]
    assert f.signature.timestamp == int.from_bytes(data[-12:-6], "little")


def _stream_frames(framer: Framer, pieces: list[bytes]) -> list[tuple[bytes, CrcStatus]]:
    sf = StreamFramer(framer, "s")
    out = []
    for i, piece in enumerate(pieces):
        sf.feed(piece, i + 1, None)
        found, _ = sf.take(False)
        out.extend((buf[pos : pos + size], st) for buf, pos, size, st, *_ in found)
    found, _ = sf.take(True)
    out.extend((buf[pos : pos + size], st) for buf, pos, size, st, *_ in found)
    return out


def _telemetry_stream(n: int = 40) -> list[bytes]:
    mav = pmav.mav2()
    frames = []
    for i in range(n):
        # STATUSTEXT payloads full of 0xFD/0xFE: false frame starts inside payloads.
        frames.append(mav.statustext_encode(6, bytes([0xFD, 0x20, 0, 0, 0xFE, 0x30]) + b"x%d" % i).pack(mav))
        frames.append(pmav.heartbeat(mav))
    return frames


def test_stream_split_at_every_byte(framer: Framer) -> None:
    frames = _telemetry_stream(3)
    data = b"".join(frames)
    for cut in range(1, len(data)):
        got = _stream_frames(framer, [data[:cut], data[cut:]])
        assert [g for g, _ in got] == frames, cut


def test_stream_resync_has_no_phantom_frames(framer: Framer) -> None:
    frames = _telemetry_stream(40)
    data = b"".join(frames)
    rng = random.Random(7)
    # Start the stream in the middle of a frame whose payload holds false STX bytes.
    start = len(frames[0]) // 2
    pieces = []
    pos = start
    while pos < len(data):
        step = rng.randint(1, 60)
        pieces.append(data[pos : pos + step])
        pos += step
    got = _stream_frames(framer, pieces)
    assert [g for g, _ in got] == frames[1:]
    assert all(st is CrcStatus.OK for _, st in got)


def test_stream_corrupted_frame_between_good_ones(framer: Framer) -> None:
    frames = _telemetry_stream(5)
    bad = bytearray(frames[4])
    bad[12] ^= 0xFF
    stream = frames[:4] + [bytes(bad)] + frames[5:]
    got = _stream_frames(framer, [b"".join(stream)])
    assert [g for g, _ in got] == stream
    assert [st for _, st in got].count(CrcStatus.BAD) == 1


def test_stream_end_truncates(framer: Framer) -> None:
    frames = _telemetry_stream(2)
    got = _stream_frames(framer, [b"".join(frames) + frames[0][:9]])
    assert got[-1] == (frames[0][:9], CrcStatus.TRUNCATED)
    assert [g for g, _ in got[:-1]] == frames
