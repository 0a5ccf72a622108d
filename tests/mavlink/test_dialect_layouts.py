"""Layouts a dialect can define that the native table cannot hold (issue 35, item 6 e): both engines give
the same output, a message the C table cannot describe going to the Python path.

What pymavlink does, read by hand (2.4.50): mavparse checks no payload length (it records
`largest_payload`), so a message over 255 bytes loads; MAVLink 2's length field is one byte, so no
frame carries more than 255 bytes of it, and pymavlink's decoder pads a shorter payload with zeros
(mavgen_python's `decode`: "the payload is zero-extended to the message's length"). mavscope does the
same. The frames are built here by hand: header, payload (MAVLink 2 drops trailing zeros), CRC-16/MCRF4XX
over header and payload and the CRC_EXTRA pymavlink's parser gives the message. Expected values are the
bytes put in, with zeros past the payload.
"""

from __future__ import annotations

import contextlib
import io
import json
import struct
from pathlib import Path

from pymavlink.generator import mavparse

from mavscope.mavlink.dialect import load_dialect
from mavscope.native.table_blob import python_only
from tests.conftest import Cli
from tests.native.build import frame_v2
from tests.native.engines import same
from tests.support.flows import T0, write_tlog

LONG = "L" * 128  # the longest name a dialect may give
DIALECT = f"""<?xml version="1.0"?>
<mavlink><enums><enum name="TEST_MANY">{"".join(f'<entry name="TEST_MANY_{i}" value="{i}"/>' for i in range(3000))}
</enum></enums><messages>
<message id="60700" name="TEST_BIG"><description>300 bytes</description>
  <field type="uint8_t[255]" name="a">a</field><field type="uint8_t[45]" name="b">b</field></message>
<message id="60701" name="TEST_FULL"><description>255 bytes</description>
  <field type="char[255]" name="text">t</field></message>
<message id="60702" name="TEST_MANY_FIELDS"><description>64 fields, 256 bytes</description>
  {"".join(f'<field type="uint32_t" name="f{i}">f</field>' for i in range(64))}</message>
<message id="60703" name="TEST_WIDE"><description>62 fields, 255 bytes</description>
  {"".join(f'<field type="uint32_t" name="f{i}">f</field>' for i in range(60))}
  <field type="uint8_t" name="g0" enum="TEST_MANY">g</field><field type="uint8_t[14]" name="g1">g</field></message>
<message id="60704" name="{LONG}"><description>long names</description>
  <field type="uint16_t" name="{LONG.lower()}">x</field><extensions/>
  <field type="uint8_t[200]" name="{LONG.lower()[:-1]}y">y</field><field type="float" name="z">z</field></message>
</messages></mavlink>
"""


def crc_extras(path: Path) -> dict[int, int]:
    with contextlib.redirect_stdout(io.StringIO()):
        xml = mavparse.MAVXML(str(path), "2.0")
    return {m.id: m.crc_extra for m in xml.message}


def frame(msgid: int, payload: bytes, crc_extra: int, seq: int) -> bytes:
    payload = payload.rstrip(b"\x00") or b"\x00"  # MAVLink 2 drops trailing zeros (keeps one byte)
    assert len(payload) <= 255
    return frame_v2(None, msgid, payload, seq, 1, 1, crc_extra=crc_extra)


def test_layouts_past_the_native_table_read_alike_on_both_engines(tmp_path: Path, cli: Cli) -> None:
    xml = tmp_path / "layouts.xml"
    xml.write_text(DIALECT)
    extra = crc_extras(xml)
    d = load_dialect([xml], environ={"MAVSCOPE_NO_CACHE": "1"})
    lengths = {mid: d.messages[mid].length for mid in extra}
    assert lengths == {60700: 300, 60701: 255, 60702: 256, 60703: 255, 60704: 206}  # by hand: sizes times counts
    assert [python_only(d.messages[mid]) for mid in sorted(extra)] == [True, False, True, False, False]
    big = bytes(range(1, 256))  # a[0..254] = 1..255: the whole frame; b is past the payload
    wide = b"".join(struct.pack("<I", i) for i in range(60)) + bytes(range(7, 22))
    frames = [frame(60700, big, extra[60700], 0), frame(60701, b"hello" + bytes(250), extra[60701], 1),
              frame(60702, struct.pack("<63I", *range(63)) + bytes(3), extra[60702], 2),
              frame(60703, wide, extra[60703], 3),
              frame(60704, struct.pack("<H", 513) + bytes(range(200)) + struct.pack("<f", 0.5), extra[60704], 4)]
    cap = write_tlog(tmp_path, [(T0 + i, f) for i, f in enumerate(frames)])
    summary = same(cli, cap, "--dialect", str(xml), fmt=())
    assert summary.status == 0 and summary.err == "" and len(summary.out.splitlines()) == 5
    lines = same(cli, cap, "--dialect", str(xml))
    assert lines.status == 0 and lines.err == ""
    fields = [json.loads(line)["fields"] for line in lines.out.splitlines()]
    assert fields[0] == {"a": list(range(1, 256)), "b": [0] * 45}  # zero-extended, as pymavlink decodes
    assert fields[1] == {"text": "hello"}
    assert fields[2] == {**{f"f{i}": i for i in range(63)}, "f63": 0}
    assert fields[3] == {**{f"f{i}": i for i in range(60)}, "g0": 7, "g1": list(range(8, 22))}
    assert fields[4] == {LONG.lower(): 513, LONG.lower()[:-1] + "y": list(range(200)), "z": 0.5}


def test_decode_many_is_decode_of_each_payload() -> None:
    """MessageDef.decode_many (one struct.iter_unpack over padded payloads for a message of scalar fields,
    what the analyses' batches decode with) against `decode` of each payload: every message of the default
    dialect, payloads of every length from 0 to the message's (zero-extended as a truncated MAVLink 2
    payload is), random bytes (NaN floats compared by repr); `decode` is the decoder the pymavlink cross-checks
    hold (tests/crosscheck)."""
    import random

    rng = random.Random(36)
    for md in load_dialect().messages.values():
        payloads = [bytes(rng.randrange(256) for _ in range(k)) for k in range(md.length + 1)]
        assert repr(md.decode_many(payloads)) == repr([md.decode(p) for p in payloads]), md.name
        assert md.decode_many([]) == []
