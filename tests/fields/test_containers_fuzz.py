"""Property tests: the container dissectors are total. Any payload bytes, of any length (shorter than
the message, as a v2 sender trims it, or longer), give fields or a malformed marker, never an exception,
and every tree item's bytes lie inside its frame."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.generator.mavcrc import x25crc

from mavscope.fields.containers import SPECS
from mavscope.fields.registry import field
from mavscope.fields.tree import flatten, frame_items
from mavscope.filter import compile_filter
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.frame import CrcStatus, Frame
from tests.fields.support import frame_of, ftp_frame

DIALECT: Dialect = load_dialect()
NAMES = {spec.name for spec in SPECS}
CONTAINERS = ("FILE_TRANSFER_PROTOCOL", "LOG_DATA", "TUNNEL", "SERIAL_CONTROL", "ENCAPSULATED_DATA")
FILTERS = [compile_filter(text, DIALECT) for text in (
    "ftp.opcode == OpenFileRO", 'ftp.path contains "a"', "ftp.error == EOF", "ftp.entry.size > 3",
    'ftp.entry.name == "x"', "ftp.malformed", "ftp.data contains 00", "log.data", "tunnel.payload contains 01",
    'serial.text matches "."', "encap.data", "serial.malformed or log.malformed or tunnel.malformed",
)]


def v2_frame(name: str, payload: bytes) -> Frame:
    """A v2 frame of message `name` with exactly `payload` (any length up to 255), its CRC right."""
    md = DIALECT.by_name[name]
    body = bytes([len(payload), 0, 0, 7, 1, 1]) + md.id.to_bytes(3, "little") + payload
    crc = x25crc(body)
    crc.accumulate(bytes([md.crc_extra]))
    return frame_of(b"\xfd" + body + crc.crc.to_bytes(2, "little"), DIALECT)


def check(frame: Frame) -> None:
    assert frame.crc_status is CrcStatus.OK
    payload_end = frame.header_len + frame.length  # a container's bytes never reach into the CRC
    for it in flatten(frame_items(frame, DIALECT)):
        assert it.offset >= 0 and it.length >= 0 and isinstance(it.label, str), it
        if it.name in NAMES and it.length:  # (a field the sender trimmed covers no bytes)
            assert frame.header_len <= it.offset and it.offset + it.length <= payload_end, it
    for spec in SPECS:
        f = field(spec.name)
        f.get(frame)
        pos = f.position(frame)
        assert pos is None or pos[1] == 0 or (frame.header_len <= pos[0] and sum(pos) <= payload_end)
    for flt in FILTERS:
        assert flt.matches(frame) in (True, False)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=251), st.sampled_from([1, 2]))
def test_any_ftp_payload(payload: bytes, version: int) -> None:
    check(ftp_frame(DIALECT, payload, version))


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(CONTAINERS), st.binary(max_size=255))
def test_any_payload_length(name: str, payload: bytes) -> None:
    check(v2_frame(name, payload))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 0xFFFF), st.sampled_from([0, 1, 2, 3, 4, 5, 13, 14, 15, 128, 129, 200]),
       st.integers(0, 255), st.sampled_from([0, 3, 4, 5, 14, 15, 77]), st.binary(max_size=239))
def test_structured_ftp(seq: int, opcode: int, size: int, req: int, data: bytes) -> None:
    """Valid-looking headers with any size and data: the shapes random bytes rarely hit."""
    header = seq.to_bytes(2, "little") + bytes([1, opcode, size, req, 0, 0]) + (1234).to_bytes(4, "little")
    check(ftp_frame(DIALECT, header + data))
