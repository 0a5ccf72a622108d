"""Every frame of the bundled captures decodes as pymavlink (an independent implementation) decodes it.

For each frame mavscope reports: pymavlink's own `decode` of the same bytes must agree on the header,
the CRC verdict (pymavlink rejects what we call bad, returns MAVLink_unknown for what we call
unchecked) and every field value. And pymavlink's robust stream parser, fed the same payloads, must
find exactly the CRC-valid frames we find.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import all as pm

from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import CAPTURES

DISSECTORS = CAPTURES.parent / "dissectors"
BUNDLED = sorted(p for p in CAPTURES.glob("*") if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))


def dissect(path: Path, dialect: Dialect) -> tuple[list[Frame], list[Anomaly]]:
    frames: list[Frame] = []
    anomalies: list[Anomaly] = []
    with open_capture(path) as reader:
        for item in Dissector(dialect).run(reader):
            (anomalies if isinstance(item, Anomaly) else frames).append(item)
    return frames, anomalies


def _same(a: object, b: object) -> bool:
    if isinstance(a, str) and isinstance(b, str) and "\x00" in a:
        # pymavlink 2.4.50 cuts a char array at its first NUL (`value.split(b"\x00", 1)[0]` in each message's
        # __init__), as mavscope cuts a string; PARAM_EXT_*.param_value carries a value's bytes (the extended
        # parameter protocol), which mavscope keeps whole but for trailing NULs (dialect.VALUE_BYTES)
        return a.split("\x00", 1)[0] == b
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


def _pymavlink_value(msg: pm.MAVLink_message, name: str) -> object:
    value = msg.format_attr(name)
    return list(value) if isinstance(value, (list, tuple)) else value


@pytest.mark.skipif(not BUNDLED, reason="captures/ is empty: run scripts/make_captures.py")
@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_frames_decode_as_pymavlink_does(path: Path, dialect: Dialect) -> None:
    frames, _ = dissect(path, dialect)
    assert frames, f"no MAVLink frames found in {path.name}"
    mav = pm.MAVLink(None)
    for f in frames:
        where = f"{path.name} frame {f.record}.{f.index}"
        if f.crc_status is CrcStatus.TRUNCATED:
            continue
        if f.crc_status is CrcStatus.BAD:
            with pytest.raises(pm.MAVError, match="CRC"):
                mav.decode(bytearray(f.raw))
            continue
        msg = mav.decode(bytearray(f.raw))
        if f.crc_status is CrcStatus.UNCHECKED or _own_message(f):
            assert isinstance(msg, pm.MAVLink_unknown), where  # pymavlink reports its own id -2
            continue
        hdr = msg.get_header()
        assert (hdr.seq, hdr.srcSystem, hdr.srcComponent, hdr.msgId) == (f.seq, f.sysid, f.compid, f.msgid), where
        assert msg.get_type() == f.msgname, where
        assert msg.get_crc() == f.crc, where
        fields = decode_payload(f)
        if f.encryption_method or f.incompat_flags & ~0x01:
            assert fields is None, where
            continue
        assert fields is not None, where
        assert list(fields) == list(msg.ordered_fieldnames), where
        for name in msg.get_fieldnames():
            assert _same(fields[name], _pymavlink_value(msg, name)), f"{where} {name}"


def _own_message(f: Frame) -> bool:
    """A message of mavscope's own dialect (dissectors/): pymavlink does not know it."""
    return f.msgdef is not None and (DISSECTORS / Path(f.msgdef.source).name).is_file()


def pymavlink_valid_frames(path: Path) -> list[bytes]:
    """CRC-valid frames pymavlink's robust parser finds in the transport payloads of a capture."""
    from mavscope.transport.decap import Decapsulator

    decap = Decapsulator()
    parsers: dict[object, pm.MAVLink] = {}
    found: list[bytes] = []

    def parse(stream: object, data: bytes) -> None:
        mav = parsers.get(stream) if stream is not None else None
        if mav is None:
            mav = pm.MAVLink(None)
            mav.robust_parsing = True
            if stream is not None:
                parsers[stream] = mav
        for m in mav.parse_buffer(data) or []:
            if not isinstance(m, (pm.MAVLink_bad_data, pm.MAVLink_unknown)):
                found.append(bytes(m.get_msgbuf()))

    with open_capture(path) as reader:
        for rec in reader:
            for p in decap.feed(rec):
                parse(p.stream, p.data)
        for p in decap.flush():
            parse(p.stream, p.data)
    return found


@pytest.mark.skipif(not BUNDLED, reason="captures/ is empty: run scripts/make_captures.py")
@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_crc_valid_frames_are_those_pymavlink_finds(path: Path, dialect: Dialect) -> None:
    frames, _ = dissect(path, dialect)
    ours = sorted(f.raw for f in frames if f.crc_status is CrcStatus.OK and not f.incompat_flags & ~0x01
                  and not _own_message(f))
    theirs = sorted(pymavlink_valid_frames(path))
    damaged = any(n.code in ("truncated-frame", "skipped-bytes", "bad-crc") for f in frames for n in f.notes)
    if not damaged:
        assert ours == theirs
        return
    # After damage pymavlink's stream parser can swallow good frames (it trusts the length of a frame
    # cut short). mavscope must find every frame pymavlink finds, and each extra one must be a frame
    # pymavlink's own decoder accepts on its own.
    missing = Counter(theirs) - Counter(ours)
    assert not missing
    mav = pm.MAVLink(None)
    for raw in (Counter(ours) - Counter(theirs)).elements():
        assert mav.decode(bytearray(raw)).get_type() != "BAD_DATA"
