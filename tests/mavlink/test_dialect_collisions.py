"""A dialect that meets another (issue 35, item 6 c): within a dialect and its includes a name or id defined
twice is refused, as mavgen refuses it; against the dialects loaded before, a name never changes meaning,
MAVLink's standard messages keep theirs, and every redefinition is one line on stderr naming the file,
the name and which definition is used. Both engines print the same.

The rules, read by hand: pymavlink 2.4.50's mavparse.check_duplicates (run by mavgen over a dialect and its
includes) fails on a message id or name defined twice, a field twice in a message, an enum entry name or
value twice in one (merged) enum; merge_enums keeps the first description. COMMAND_LONG is message 76 and
MAV_CMD_COMPONENT_ARM_DISARM is 400 in common.xml; SENSOR_OFFSETS is 150 in ardupilotmega.xml; both as
common.xml and ardupilotmega.xml say.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from mavscope.errors import DialectError
from mavscope.mavlink.dialect import Dialect, load_dialect, pymavlink_dialect_path
from tests.conftest import Cli
from tests.native.engines import same
from tests.support import flows
from tests.support.flows import T0, write_tlog

V20 = pymavlink_dialect_path("all").parent
NO_CACHE = {"MAVSCOPE_NO_CACHE": "1"}


def dialect_file(folder: Path, name: str, messages: str = "", enums: str = "", include: str = "") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(f'<?xml version="1.0"?>\n<mavlink>{include}<enums>{enums}</enums><messages>{messages}'
                    "</messages></mavlink>\n")
    return path


def msg(name: str, mid: int, fields: str = '<field type="uint8_t" name="a">a</field>') -> str:
    return f'<message id="{mid}" name="{name}"><description>d</description>{fields}</message>'


def entry(enum: str, name: str, value: int) -> str:
    return f'<enum name="{enum}"><entry name="{name}" value="{value}"/></enum>'


def loaded(*files: Path) -> tuple[Dialect, list[str]]:
    warnings: list[str] = []
    return load_dialect(files, environ=NO_CACHE, warn=warnings.append), warnings


# --- within a dialect and its includes: refused, as mavgen does ----------------------------------------

@pytest.mark.parametrize(("messages", "enums", "why"), [
    (msg("TEST_A", 60500) + msg("TEST_B", 60500), "", "message id 60500 is both TEST_B and TEST_A (x.xml)"),
    (msg("TEST_A", 60500) + msg("TEST_A", 60501), "", "message TEST_A is both id 60501 and id 60500 (x.xml)"),
    (msg("TEST_A", 60500, '<field type="uint8_t" name="a">a</field><field type="float" name="a">b</field>'), "",
     "message TEST_A has field a twice"),
    (msg("TEST_A", 60500, '<field type="uint8_t" name="lat">a</field><field type="float" name="LAT">b</field>'), "",
     "message TEST_A has fields LAT and lat, which differ only in case (SQL and many file systems do not tell "
     "them apart)"),  # in wire order: the float first
    ("", entry("TEST_E", "TEST_E_A", 1) + entry("TEST_E", "TEST_E_B", 1),
     "enum TEST_E value 1 is both TEST_E_B and TEST_E_A (x.xml)"),
    ("", entry("TEST_E", "TEST_E_A", 1) + entry("TEST_F", "TEST_E_A", 2),
     "enum entry TEST_E_A is both TEST_F 2 and TEST_E 1 (x.xml)"),
])
def test_a_name_or_id_twice_in_one_dialect_is_refused(tmp_path: Path, messages: str, enums: str, why: str) -> None:
    path = dialect_file(tmp_path, "x.xml", messages, enums)
    with pytest.raises(DialectError) as e:
        Dialect().load(path)
    assert str(e.value) == f"{path.resolve()}: cannot load dialect: {why}"


def test_a_dialect_that_includes_common_xml_cannot_redefine_its_ids(tmp_path: Path) -> None:
    """The usual custom dialect: `<include>common.xml</include>` and its own messages; one that reuses id 76
    is what mavgen refuses (its check runs over the dialect and the files it includes)."""
    folder = tmp_path / "d"
    for name in ("common.xml", "standard.xml", "minimal.xml"):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes((V20 / name).read_bytes())
    path = dialect_file(folder, "mine.xml", msg("HARMLESS", 76), include="<include>common.xml</include>")
    with pytest.raises(DialectError) as e:
        Dialect().load(path)
    assert str(e.value) == (f"{(folder / 'common.xml').resolve()}: cannot load dialect: message id 76 is both "
                            "COMMAND_LONG and HARMLESS (mine.xml)")
    good = dialect_file(folder, "good.xml", msg("TEST_MINE", 60500), include="<include>common.xml</include>")
    d, warnings = loaded(good)
    assert warnings == [] and d.by_name["TEST_MINE"].id == 60500  # common.xml's copy: the same definitions


# --- against the dialects loaded before -------------------------------------------------------------------

def test_a_later_message_cannot_take_a_name(tmp_path: Path) -> None:
    path = dialect_file(tmp_path, "x.xml", msg("COMMAND_LONG", 60500))
    d, warnings = loaded(path)
    assert warnings == ["x.xml: message COMMAND_LONG (id 60500) not loaded: COMMAND_LONG is message id 76 of "
                        "common.xml"]
    assert d.by_name["COMMAND_LONG"].id == 76 and 60500 not in d.messages


def test_a_later_message_cannot_redefine_a_standard_id(tmp_path: Path) -> None:
    path = dialect_file(tmp_path, "x.xml", msg("HARMLESS", 76))
    d, warnings = loaded(path)
    assert warnings == ["x.xml: message HARMLESS (id 76) not loaded: id 76 is COMMAND_LONG of common.xml, one of "
                        "MAVLink's standard messages"]
    assert d.messages[76].name == "COMMAND_LONG" and "HARMLESS" not in d.by_name


def test_a_later_dialect_may_redefine_a_vendor_id_and_says_so(tmp_path: Path) -> None:
    """A vendor's dialect for its own vehicles (pymavlink's matrixpilot.xml reuses ardupilotmega's ids so),
    and docs/security.md's advice for MAVSCOPE_KEY_EXCHANGE's 65100: the file asked for wins, said."""
    path = dialect_file(tmp_path, "x.xml", msg("VENDOR_THING", 150) + msg("VENDOR_KEYS", 65100))
    d, warnings = loaded(path)
    assert warnings == ["x.xml: message VENDOR_THING (id 150) replaces SENSOR_OFFSETS of ardupilotmega.xml",
                        "x.xml: message VENDOR_KEYS (id 65100) replaces MAVSCOPE_KEY_EXCHANGE of mavscope.xml"]
    assert d.messages[150].name == "VENDOR_THING" and "SENSOR_OFFSETS" not in d.by_name


def test_a_later_enum_entry_cannot_rename_a_value_or_move_a_name(tmp_path: Path) -> None:
    enums = ('<enum name="MAV_CMD"><entry name="MAV_CMD_HARMLESS" value="400"/>'
             '<entry name="MAV_CMD_COMPONENT_ARM_DISARM" value="9999"/><entry name="MAV_CMD_TEST_NEW" value="9998"/>'
             '</enum><enum name="TEST_E"><entry name="MAV_CMD_NAV_WAYPOINT" value="1"/></enum>')
    d, warnings = loaded(dialect_file(tmp_path, "x.xml", enums=enums))
    assert warnings == [
        "x.xml: enum entry MAV_CMD.MAV_CMD_HARMLESS = 400 not loaded: 400 is MAV_CMD.MAV_CMD_COMPONENT_ARM_DISARM "
        "of an earlier dialect",
        "x.xml: enum entry MAV_CMD.MAV_CMD_COMPONENT_ARM_DISARM = 9999 not loaded: MAV_CMD_COMPONENT_ARM_DISARM is "
        "an entry of MAV_CMD already",
        "x.xml: enum entry TEST_E.MAV_CMD_NAV_WAYPOINT = 1 not loaded: MAV_CMD_NAV_WAYPOINT is an entry of MAV_CMD "
        "already"]
    assert d.enums["MAV_CMD"].name_of(400) == "MAV_CMD_COMPONENT_ARM_DISARM"
    assert d.enum_value("MAV_CMD_COMPONENT_ARM_DISARM") == ("MAV_CMD", 400)
    assert d.enums["MAV_CMD"].name_of(9998) == "MAV_CMD_TEST_NEW"  # a new entry of an existing enum: merged


def test_a_filter_keeps_its_meaning_and_both_engines_say_why(tmp_path: Path, cli: Cli) -> None:
    """The issue's instance: a dialect reusing COMMAND_LONG made `-Y COMMAND_LONG` match nothing. The
    arm command (COMMAND_LONG, MAV_CMD_COMPONENT_ARM_DISARM) is still found, and stderr says what was not
    loaded, the same line from either engine."""
    gcs = flows.Sender(255, 190)
    cap = write_tlog(tmp_path, [(T0, gcs.pack(flows.heartbeat(gcs=True))), (T0 + 1, gcs.pack(flows.command_long(400)))])
    evil = dialect_file(tmp_path, "evil.xml", msg("COMMAND_LONG", 60500) + msg("HARMLESS", 76))
    for args in ((), ("-T", "jsonl")):
        got = same(cli, cap, "--dialect", str(evil), "-Y", "COMMAND_LONG", fmt=args)
        assert got.status == 0
        assert got.err == ("mavscope: evil.xml: message COMMAND_LONG (id 60500) not loaded: COMMAND_LONG is message "
                           "id 76 of common.xml\n"
                           "mavscope: evil.xml: message HARMLESS (id 76) not loaded: id 76 is COMMAND_LONG of "
                           "common.xml, one of MAVLink's standard messages\n")
        assert len(got.out.splitlines()) == 1 and "COMMAND_LONG" in got.out
