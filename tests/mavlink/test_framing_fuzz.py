"""Mutation tests on the framer and the whole pipeline: no exception escapes, no byte vanishes (each is in one
frame or in skipped bytes; a frame MAVLink's C library reads inside another, tests/mavlink/test_hidden_frames.py,
lies in that one's bytes)."""

from __future__ import annotations

import re

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mavscope.capture.base import LINKTYPE_MAVLINK_RAW, LINKTYPE_MAVLINK_TLOG, Record
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.support.builders import mixed_frames

_DIALECT: Dialect = load_dialect()
_SETTINGS = settings(max_examples=150, deadline=None, derandomize=True,
                     suppress_health_check=[HealthCheck.too_slow])


SESSION = b"".join(mixed_frames())


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    data = bytearray(SESSION)
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.sampled_from(["flip", "cut", "insert", "len"]))
        if not data:
            break
        pos = draw(st.integers(0, len(data) - 1))
        if kind == "flip":
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif kind == "cut":
            del data[pos : pos + draw(st.integers(1, 40))]
        elif kind == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=20))
        else:
            data[pos] = draw(st.sampled_from([0xFD, 0xFE]))
            if pos + 1 < len(data):
                data[pos + 1] = draw(st.sampled_from([0, 1, 255]))
    return bytes(data)


def _top(items: list[Frame | Anomaly]) -> list[Frame]:
    """The frames that cover the bytes: not those MAVLink's C library reads inside them (hidden-frame)."""
    return [i for i in items if isinstance(i, Frame) and not any(n.code == "hidden-frame" for n in i.notes)]


def _skipped(items: list[Frame | Anomaly]) -> int:
    total = 0
    for item in items:
        for n in item.notes:
            if n.code == "skipped-bytes":
                total += int(re.match(r"(\d+) bytes", n.message).group(1))  # type: ignore[union-attr]
    return total


@_SETTINGS
@given(data=mutated(), chunk=st.integers(1, 97))
def test_raw_stream_conserves_every_byte(data: bytes, chunk: int) -> None:
    records = [
        Record(i + 1, None, LINKTYPE_MAVLINK_RAW, data[off : off + chunk], off, len(data[off : off + chunk]))
        for i, off in enumerate(range(0, len(data), chunk))
    ]
    items = list(Dissector(_DIALECT).run(records))
    assert sum(len(f.raw) for f in _top(items)) + _skipped(items) == len(data)
    for f in (i for i in items if isinstance(i, Frame)):
        assert f.offset is not None and data[f.offset : f.offset + len(f.raw)] == f.raw


@_SETTINGS
@given(data=mutated())
def test_tlog_entry_conserves_every_byte(data: bytes) -> None:
    # A tlog entry is a trusted datagram: frames plus skipped bytes cover it exactly.
    items = list(Dissector(_DIALECT).run([Record(1, 1.0, LINKTYPE_MAVLINK_TLOG, data, 0, len(data))]))
    if data:
        assert sum(len(f.raw) for f in _top(items)) + _skipped(items) == len(data)


@_SETTINGS
@given(data=mutated())
def test_every_frame_renders(data: bytes) -> None:
    from mavscope.output.jsonout import jsonl_bytes
    from mavscope.output.text import detail_text, summary_line

    items = list(Dissector(_DIALECT).run([Record(1, None, LINKTYPE_MAVLINK_RAW, data, 0, len(data))]))
    for item in items:
        if isinstance(item, Frame):
            jsonl_bytes(item)
            summary_line(item, _DIALECT, None)
            detail_text(item, _DIALECT)


def test_truncation_at_every_byte() -> None:
    for cut in range(len(SESSION) + 1):
        data = SESSION[:cut]
        items = list(Dissector(_DIALECT).run([Record(1, None, LINKTYPE_MAVLINK_RAW, data, 0, len(data))]))
        assert sum(len(f.raw) for f in _top(items)) + _skipped(items) == cut


def test_garbage_tlog_entry_is_reported() -> None:
    items = list(Dissector(_DIALECT).run([Record(1, 1.0, LINKTYPE_MAVLINK_TLOG, b"\x00garbage\xfd", 8, 9)]))
    assert [type(i) for i in items] == [Anomaly]
    assert _skipped(items) == 9 and items[0].notes[0].offset == 8
