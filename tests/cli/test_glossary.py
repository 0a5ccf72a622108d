"""`read -G fields` and `read -G values`: tshark's glossary layout, every name, values from pymavlink.

The layout is tshark's own (`tshark -G fields`: P lines of 3 tab-separated cells, F lines of 8; `tshark -G
values`: V lines of 4), checked against tshark where it is installed. Every payload field of the default
dialect appears as `MSG.field` with the FT_ type its MAVLink type names, and the named values of
HEARTBEAT.type are pymavlink's MAV_TYPE entries (pymavlink's own enum tables, not mavscope's parse). A
dialect's description holding a C1 control (the 8-bit CSI), a bidi override and a tab is escaped, so it
cannot write to the terminal or add a column.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import all as v2

from tests.conftest import Cli


def _lines(cli: Cli, kind: str, *extra: str) -> list[list[str]]:
    got = cli("read", "-G", kind, *extra)
    assert got.status == 0, got.err
    return [line.split("\t") for line in got.out.splitlines()]


def test_fields_layout_and_payload_fields(cli: Cli) -> None:
    rows = _lines(cli, "fields")
    assert {len(r) for r in rows if r[0] == "P"} == {3} and {len(r) for r in rows if r[0] == "F"} == {8}
    by_name = {r[2]: r for r in rows if r[0] == "F"}
    assert by_name["ATTITUDE.roll"][3] == "FT_FLOAT" and by_name["GLOBAL_POSITION_INT.lat"][3] == "FT_INT32"
    assert by_name["HEARTBEAT.custom_mode"][3] == "FT_UINT32" and by_name["STATUSTEXT.text"][3] == "FT_STRING"
    assert by_name["mavlink.seq"][4] == "mavlink" and "ftp.opcode" in by_name and "signature.status" in by_name
    # every field pymavlink's ATTITUDE has, by its own field list
    want = {f"ATTITUDE.{f}" for f in v2.MAVLink_attitude_message.fieldnames}
    assert {n for n in by_name if n.startswith("ATTITUDE.")} == want
    if shutil.which("tshark"):  # the same layout as tshark's glossary
        ref = subprocess.run(["tshark", "-G", "fields"], capture_output=True, text=True, timeout=120).stdout
        f_line = next(line for line in ref.splitlines() if line.startswith("F\t"))
        assert len(f_line.split("\t")) == 8


def test_values_are_pymavlinks_enums(cli: Cli) -> None:
    rows = _lines(cli, "values")
    assert {len(r) for r in rows} == {4} and {r[0] for r in rows} == {"V"}
    got = {int(r[2]): r[3] for r in rows if r[1] == "HEARTBEAT.type"}
    want = {k: e.name for k, e in v2.enums["MAV_TYPE"].items() if not e.name.endswith("_ENUM_END")}
    assert got == want


def test_a_dialects_words_are_escaped(cli: Cli, tmp_path: Path) -> None:
    xml = tmp_path / "x.xml"
    xml.write_text('<?xml version="1.0"?><mavlink><messages><message id="42420" name="EVIL">'
                   "<description>x</description><field type=\"uint8_t\" name=\"a\">boom&#9;&#x9b;2J&#x202e;</field>"
                   "</message></messages></mavlink>")
    got = cli("read", "-G", "fields", "--dialect", str(xml))
    assert got.status == 0, got.err
    line = next(line for line in got.out.splitlines() if "\tEVIL.a\t" in line)
    # the 8-bit CSI (U+009B) and a right-to-left override as repr writes them, no ninth cell (the XML
    # parser makes the tab a space)
    assert "\x9b" not in got.out and "\u202e" not in got.out and len(line.split("\t")) == 8
    assert "\\x9b2J\\u202e" in line


def test_no_capture_with_a_glossary(cli: Cli, tmp_path: Path) -> None:
    got = cli("read", str(tmp_path / "x.pcap"), "-G", "fields")
    assert got.status == 2 and "give no FILE" in got.err


@pytest.mark.parametrize("kind", ["fields", "values"])
def test_glossary_is_deterministic(cli: Cli, kind: str) -> None:
    assert cli("read", "-G", kind).out == cli("read", "-G", kind).out
