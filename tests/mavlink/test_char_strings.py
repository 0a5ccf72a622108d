"""char[N] strings end at their first NUL (issue 35, item 9), everywhere a char array's value is made: the
decoder, JSON Lines and summary lines of both engines, filters, the detail tree, the export's columns, the
parameter tracker (`params --out`) and param.pck names; the bytes after that NUL are a `char-after-nul`
note (the field, the count), never part of the value.

Expected values come from pymavlink's own decoder of the same bytes: its generated messages keep
`value.split(b"\\x00", 1)[0]` (pymavlink/generator/mavgen_python.py, the `init_fields` of each message
class: `self.param_id = param_id.split(b"\\x00", 1)[0].decode("ascii", errors="replace")`, 2.4.50). The
byte counts of the notes and the tree's byte ranges are counted by hand from the bytes built here.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

from mavscope.analysis.params.pck import decode as pck_decode
from mavscope.capture.detect import open_capture
from mavscope.export import ExportOptions, record_batches, table_of
from mavscope.fields.tree import flatten, frame_items
from mavscope.mavlink.dialect import Dialect, char_tail, char_text
from mavscope.mavlink.frame import Frame, decode_payload
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import Cli
from tests.native.engines import same
from tests.support import flows
from tests.support.flows import T0, write_tlog, write_udp_pcap
from tests.support.pmav import mav1
from tests.support.pymavlink_reader import read as pymavlink_read

v2 = flows.v2
SYS_ID = b"SYS_ID" + b"\x00" * 9 + b"S"  # 16 bytes, as px4flow_v1_encapsulated_data.tlog's first PARAM_VALUE
JUNK = b"hello\x00junk after"  # a STATUSTEXT whose 50 bytes carry more after the string's NUL


def _sender(sysid: int = 81, compid: int = 50) -> flows.Sender:
    return flows.Sender(sysid, compid)


def _frames() -> list[bytes]:
    """Frames with char arrays: bytes after the NUL (v1 and v2), none, a full array without a NUL."""
    s = _sender()
    m1 = mav1(81, 50)
    return [
        bytes(m1.param_value_encode(SYS_ID, 81.0, 9, 37, 0).pack(m1)),  # MAVLink 1, as PX4Flow sent it
        s.pack(v2.MAVLink_param_value_message(b"USB_SEND_VIDEO\x00U", 1.0, 9, 37, 1)),
        s.pack(v2.MAVLink_param_value_message(b"IMAGE_WIDTH", 64.0, 9, 37, 2)),  # clean
        s.pack(v2.MAVLink_param_value_message(b"SIXTEEN_CHARS_ID", 3.0, 9, 37, 3)),  # 16 bytes, no NUL
        s.pack(v2.MAVLink_statustext_message(4, JUNK)),
        s.pack(v2.MAVLink_statustext_message(6, b"clean text")),
        s.pack(v2.MAVLink_named_value_int_message(1000, b"GYRO\x00\x00\x000", 7)),
        s.pack(v2.MAVLink_debug_vect_message(b"GYRO\x00\x00\x00\x000", 1, 0.5, 0.25, 0.125)),
    ]


# by hand: (message, field, value, bytes after the NUL up to the last non-NUL byte)
EXPECTED = [("PARAM_VALUE", "param_id", "SYS_ID", 9), ("PARAM_VALUE", "param_id", "USB_SEND_VIDEO", 1),
            ("PARAM_VALUE", "param_id", "IMAGE_WIDTH", 0), ("PARAM_VALUE", "param_id", "SIXTEEN_CHARS_ID", 0),
            ("STATUSTEXT", "text", "hello", len("junk after")), ("STATUSTEXT", "text", "clean text", 0),
            ("NAMED_VALUE_INT", "name", "GYRO", 3), ("DEBUG_VECT", "name", "GYRO", 4)]


def _dissect(path: str, dialect: Dialect) -> list[Frame]:
    with open_capture(path) as r:
        return [f for f in Dissector(dialect).run(r) if type(f) is not Anomaly]


@pytest.fixture()
def tlog_path(tmp_path: Path) -> str:
    return write_tlog(tmp_path, [(T0 + i * 0.1, f) for i, f in enumerate(_frames())])


@pytest.fixture()
def pcap_path(tmp_path: Path) -> str:
    # one datagram per frame, vehicle to ground station: the native engine's UDP path and the fast path
    packets = [(("10.0.0.2", 14555), ("10.0.0.1", 14550), f) for f in _frames()]
    return str(write_udp_pcap(tmp_path / "strings.pcap", packets))


def test_char_rule_by_hand() -> None:
    assert (char_text(SYS_ID), char_tail(SYS_ID)) == ("SYS_ID", 9)
    assert (char_text(b"AB\x00\x00"), char_tail(b"AB\x00\x00")) == ("AB", 0)  # padding only
    assert (char_text(b"ABCD"), char_tail(b"ABCD")) == ("ABCD", 0)  # a full array has no NUL
    assert (char_text(b"\x00x"), char_tail(b"\x00x")) == ("", 1)


@pytest.mark.parametrize("kind", ["tlog", "pcap"])
def test_values_are_pymavlinks_and_the_rest_is_a_note(kind: str, tlog_path: str, pcap_path: str,
                                                      dialect: Dialect) -> None:
    frames = _dissect(tlog_path if kind == "tlog" else pcap_path, dialect)
    assert len(frames) == len(EXPECTED)
    pm = v2.MAVLink(None)
    for f, (name, field, value, tail) in zip(frames, EXPECTED):
        msg = pm.decode(bytearray(f.raw))
        assert (f.msgname, decode_payload(f)[field]) == (name, getattr(msg, field)) == (name, value)  # type: ignore[index]
        notes = [n for n in f.notes if n.code == "char-after-nul"]
        if tail:
            assert [n.message for n in notes] == [
                f"{name}.{field}: {tail} byte{'s' if tail > 1 else ''} after the NUL that ends the string "
                "(not part of its value)"]
        else:
            assert notes == []


def test_the_tree_shows_the_bytes_after_the_nul(tlog_path: str, dialect: Dialect) -> None:
    f = _dissect(tlog_path, dialect)[0]  # MAVLink 1 PARAM_VALUE: 6-byte header, param_id at payload offset 8
    items = [it for it in flatten(frame_items(f, dialect)) if it.name == "note.char-after-nul"]
    payload_item = items[0]
    # param_value (4) + param_count (2) + param_index (2) come first: param_id at frame byte 6 + 8 = 14; its
    # NUL at 14 + 6 = 20; the 9 bytes after it, 21..29, the last one the "S"
    assert (payload_item.offset, payload_item.length, payload_item.value) == (21, 9, b"\x00" * 8 + b"S")
    assert f.raw[29:30] == b"S"


@pytest.mark.parametrize("kind", ["tlog", "pcap"])
def test_both_engines_alike(cli: Cli, kind: str, tlog_path: str, pcap_path: str) -> None:
    path = tlog_path if kind == "tlog" else pcap_path
    rows = [json.loads(line) for line in same(cli, path).out.splitlines()]
    assert [r["fields"][field] for r, (_, field, _, _) in zip(rows, EXPECTED)] == [v for _, _, v, _ in EXPECTED]
    assert [sum(n["code"] == "char-after-nul" for n in r["notes"]) for r in rows] == [int(t > 0) for *_, t in EXPECTED]
    lines = same(cli, path, fmt=()).out.splitlines()
    assert "param_id='SYS_ID' " in lines[0] and "text='hello'" in lines[4]
    same(cli, path, "-Y", 'PARAM_VALUE.param_id == "SYS_ID"')
    assert cli("stats", path, environ={"MAVSCOPE_PURE": "1"}) == cli("stats", path, environ={})


def test_filters_match_the_string(cli: Cli, tlog_path: str) -> None:
    assert [r["frame"] for r in cli.jsonl(tlog_path, "-Y", 'PARAM_VALUE.param_id == "SYS_ID"')] == [1]
    assert [r["frame"] for r in cli.jsonl(tlog_path, "-Y", 'STATUSTEXT.text == "hello"')] == [5]
    assert [r["frame"] for r in cli.jsonl(tlog_path, "-Y", "note.char-after-nul")] == [1, 2, 5, 7, 8]


def test_params_out_writes_every_name(cli: Cli, tlog_path: str, tmp_path: Path) -> None:
    out = tmp_path / "p.parm"
    r = cli("params", tlog_path, "--out", str(out))
    assert r.status == 0, r.err
    names = [line.split(",")[0] for line in out.read_text().splitlines() if not line.startswith("#")]
    assert names == ["IMAGE_WIDTH", "SIXTEEN_CHARS_ID", "SYS_ID", "USB_SEND_VIDEO"]  # sorted, as the file is


@pytest.mark.parametrize("source", ["native", "python"])
def test_export_columns_hold_the_string(source: str, pcap_path: str) -> None:
    tables: dict[str, list[object]] = {}
    for b in record_batches(pcap_path, ExportOptions(source=source)):
        t = table_of(b)
        if t in ("msg=PARAM_VALUE", "msg=STATUSTEXT"):
            col = "param_id" if t == "msg=PARAM_VALUE" else "text"
            tables.setdefault(t, []).extend(b.column(col).to_pylist())
    assert tables == {"msg=PARAM_VALUE": ["SYS_ID", "USB_SEND_VIDEO", "IMAGE_WIDTH", "SIXTEEN_CHARS_ID"],
                      "msg=STATUSTEXT": ["hello", "clean text"]}


def test_param_ext_value_keeps_its_bytes(dialect: Dialect, tmp_path: Path) -> None:
    # PARAM_EXT_VALUE.param_value carries the value's bytes (MAV_PARAM_EXT_TYPE_REAL32: a float's), where a
    # NUL is one of them: 1.0 is 00 00 80 3f. Kept but for the trailing NULs (pymavlink shows '' here), not noted.
    s = _sender()
    value = struct.pack("<f", 1.0)
    path = write_tlog(tmp_path, [(T0, s.pack(v2.MAVLink_param_ext_value_message(b"CAM_MODE", value, 9, 1, 0)))])
    (f,) = _dissect(path, dialect)
    assert decode_payload(f)["param_value"] == "\x00\x00\\x80?"  # type: ignore[index]
    assert decode_payload(f)["param_id"] == "CAM_MODE" and f.notes == ()  # type: ignore[index]


def test_param_pck_names_end_at_a_nul() -> None:
    # param.pck (ArduPilot's AP_Filesystem README): magic 0x671b, 1 parameter, 1 on the vehicle; one block:
    # type 4 (float), name of 8 new bytes ((8 - 1) << 4, none shared), the name, the value
    name = b"ARMING\x00X"
    data = struct.pack("<HHH", 0x671B, 1, 1) + bytes((4, (len(name) - 1) << 4)) + name + struct.pack("<f", 0.0)
    pck = pck_decode(data)
    assert [p.name for p in pck.params] == ["ARMING"]
    assert pck.problems == ("offset 6: the name 'ARMING' has 1 byte after a NUL, which ends it (as a char[16] "
                            "param_id ends)",)


def test_real_px4flow_params_all_written(cli: Cli, real_captures: Path, tmp_path: Path) -> None:
    """px4flow_v1_encapsulated_data.tlog: every PARAM_VALUE param_id carries bytes after its NUL. pymavlink
    reads 13 distinct parameter names (tests/support/pymavlink_reader.py); `params --out` writes 13 (it wrote 0)."""
    path = real_captures / "px4flow_v1_encapsulated_data.tlog"
    names = {m.msg.param_id for m in pymavlink_read(path) if m.name == "PARAM_VALUE"}
    out = tmp_path / "px4flow.parm"
    r = cli("params", str(path), "--out", str(out))
    assert r.status == 0, r.err
    written = {line.split(",")[0] for line in out.read_text().splitlines() if not line.startswith("#")}
    assert len(names) == 13 and written == names
