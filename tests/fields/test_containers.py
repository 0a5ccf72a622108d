"""LOG_DATA, TUNNEL, SERIAL_CONTROL and ENCAPSULATED_DATA: only the valid bytes are shown and registered,
nested under their array, with their byte ranges (frames built by pymavlink)."""

from __future__ import annotations

import pytest

from mavscope.fields.registry import MISSING, field
from mavscope.filter import compile_filter
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from tests.fields.support import frame_of, item, items_named, mav, wire


def pad(data: bytes, size: int) -> list[int]:
    return list(data.ljust(size, b"\0")[:size])


def log_data(dialect: Dialect, data: bytes, count: int, version: int = 2) -> Frame:
    m = mav(version, 1, 1)
    return frame_of(m.log_data_encode(3, 4096, count, pad(data, 90)).pack(m), dialect)


def tunnel(dialect: Dialect, data: bytes, length: int, payload_type: int = 0) -> Frame:
    m = mav(2, 1, 1)
    return frame_of(m.tunnel_encode(255, 190, payload_type, length, pad(data, 128)).pack(m), dialect)


def serial(dialect: Dialect, data: bytes, count: int | None = None) -> Frame:
    m = mav(2, 1, 1)
    n = len(data) if count is None else count
    return frame_of(m.serial_control_encode(10, 1, 0, 0, n, pad(data, 70)).pack(m), dialect)


def get(frame: Frame, name: str) -> object:
    return field(name).get(frame)


def matches(frame: Frame, text: str, dialect: Dialect) -> bool:
    return compile_filter(text, dialect).matches(frame)


@pytest.mark.parametrize("version", [1, 2])
def test_log_data_valid_bytes(dialect: Dialect, version: int) -> None:
    chunk = bytes(range(100, 137))  # 37 bytes, then stale bytes the count excludes
    f = log_data(dialect, chunk + b"\xee" * 20, 37, version)
    array = item(f, dialect, "LOG_DATA.data")
    assert array.label == "data: 37 of 90 bytes valid" + (" [partly trimmed: zero-filled]" if version == 2 else "")
    data = item(f, dialect, "log.data")
    assert data in array.children and data.label == f"Data (37 bytes): {chunk.hex(' ')}"
    base = (10 if version == 2 else 6) + 7  # ofs, id, count
    assert (data.offset, data.length) == (base, 37) and wire(f, data) == chunk
    assert get(f, "log.data") == chunk and get(f, "log.malformed") is MISSING
    assert matches(f, "log.data contains 64:65:66", dialect)
    assert not matches(f, "log.data contains ee:ee", dialect)  # the stale bytes are no data


def test_log_data_count_too_large(dialect: Dialect) -> None:
    f = log_data(dialect, b"\x01" * 90, 200)
    assert get(f, "log.data") == b"\x01" * 90
    marker = item(f, dialect, "log.malformed")
    assert marker.generated and marker.label == "[Malformed: LOG_DATA.data: count 200 exceeds its 90 bytes]"
    assert matches(f, "log.malformed", dialect)


def test_log_data_empty(dialect: Dialect) -> None:
    f = log_data(dialect, b"", 0)
    assert get(f, "log.data") is MISSING and item(f, dialect, "log.data").label == "Data (0 bytes): (none)"


def test_tunnel_payload(dialect: Dialect) -> None:
    f = tunnel(dialect, b"\x10\x20\x30\x40\x50", 5, payload_type=210)
    assert get(f, "tunnel.payload") == b"\x10\x20\x30\x40\x50"
    data = item(f, dialect, "tunnel.payload")
    assert wire(f, data) == b"\x10\x20\x30\x40\x50" and data.offset == 10 + 5
    assert item(f, dialect, "TUNNEL.payload").label.startswith("payload: 5 of 128 bytes valid")
    assert item(f, dialect, "TUNNEL.payload_type").label == \
        "payload_type: MAV_TUNNEL_PAYLOAD_TYPE_MODALAI_REMOTE_OSD (210)"
    assert matches(f, "tunnel.payload contains 30:40 && TUNNEL.payload_type == 210", dialect)
    assert item(tunnel(dialect, b"", 129), dialect, "tunnel.malformed").generated


def test_serial_control_text(dialect: Dialect) -> None:
    console = b"nsh> ls\r\n/fs/microsd\r\n"
    f = serial(dialect, console + b"junk", len(console))
    assert get(f, "serial.data") == console and get(f, "serial.text") == console.decode()
    text = item(f, dialect, "serial.text")
    assert text.label == f"Text: {console.decode()!r}" and wire(f, text) == console
    assert [c.name for c in item(f, dialect, "SERIAL_CONTROL.data").children] == ["serial.data", "serial.text"]
    assert matches(f, 'serial.text contains "microsd"', dialect)
    assert matches(f, 'serial.text matches "^nsh> "', dialect)


def test_serial_control_invalid_utf8(dialect: Dialect) -> None:
    f = serial(dialect, b"ok \xff\xfe")
    assert get(f, "serial.text") == "ok \\xff\\xfe"
    assert item(f, dialect, "serial.text").label.endswith("[not UTF-8: undecodable bytes escaped]")


def test_encapsulated_data_chunk(dialect: Dialect) -> None:
    m = mav(1, 81, 50)
    chunk = bytes(i % 251 for i in range(253))
    f = frame_of(m.encapsulated_data_encode(12, list(chunk)).pack(m), dialect)
    data = item(f, dialect, "encap.data")
    assert (data.offset, data.length) == (6 + 2, 253) and wire(f, data) == chunk
    assert get(f, "encap.data") == chunk
    assert item(f, dialect, "ENCAPSULATED_DATA.seqnr").label == "seqnr: 12"
    assert matches(f, "encap.data contains 00:01:02 && ENCAPSULATED_DATA.seqnr == 12", dialect)


def test_handshake_stays_ordinary(dialect: Dialect) -> None:
    m = mav(1, 81, 50)
    f = frame_of(m.data_transmission_handshake_encode(3, 4096, 64, 64, 17, 253, 0).pack(m), dialect)
    assert all(not it.children for it in item(f, dialect, "mavlink.payload").children)
    assert not items_named(f, dialect, "encap.data")


def test_encapsulated_data_real_capture(real_captures, dialect: Dialect) -> None:  # type: ignore[no-untyped-def]
    """PX4Flow's image chunks: `encap.data` is what pymavlink reads, chunk by chunk (v1 frames)."""
    from pymavlink import mavutil

    from mavscope.capture.detect import open_capture
    from mavscope.pipeline.dissect import Dissector

    path = real_captures / "px4flow_v1_encapsulated_data.tlog"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    conn = mavutil.mavlink_connection(str(path), dialect="common")
    chunks = []
    while (msg := conn.recv_match(type="ENCAPSULATED_DATA")) is not None:
        chunks.append(bytes(msg.data))
    with open_capture(path) as reader:
        frames = [f for f in Dissector(dialect).run(reader)
                  if isinstance(f, Frame) and f.msgname == "ENCAPSULATED_DATA"]
    assert len(chunks) == len(frames) == 3010
    assert [get(f, "encap.data") for f in frames] == chunks
