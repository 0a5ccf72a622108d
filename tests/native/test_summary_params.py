"""The Info column of `read` leaves out a command's parameters that its MAV_CMD entry leaves unlabelled and
that hold nothing (0, -0.0 or NaN), as `commands` does (issue 35 item 15): COMMAND_LONG's param1 and
COMMAND_INT's and MISSION_ITEM(_INT)'s x, y, z (params 5..7), on both engines, byte for byte.

Expected lines, by hand from common.xml's MAV_CMD entries: MAV_CMD_NAV_RETURN_TO_LAUNCH (20) has seven
`<param>`s without a label ("Empty"); MAV_CMD_NAV_TAKEOFF (22) labels param1 "Pitch"; MAV_CMD_DO_REPOSITION
(192) labels params 5..7 Latitude, Longitude, Altitude; MAV_CMD_DO_SET_MODE (176) labels params 1..3 only;
command 65000 is no MAV_CMD entry (nothing labelled). A labelled parameter is shown whatever it holds; an
unlabelled one only when it holds something else than 0 or NaN. The values' texts are those the summary
writes for any field (float32 shortest, x/y of the *_INT messages in degrees: 1 -> 0.0000001).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from tests.conftest import Cli
from tests.native.engines import native_summary_output
from tests.support import flows

native = pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

NAN = math.nan
RTL, TAKEOFF, SET_MODE, REPOSITION, UNDEFINED = 20, 22, 176, 192, 65000
TARGET = "target_system=1 target_component=1"

# (message, Info the summary shows)
CASES: list[tuple[object, str]] = [
    (v2.MAVLink_command_long_message(1, 1, RTL, 0, 0, 0, 0, 0, 0, 0, 0),
     f"COMMAND_LONG command=MAV_CMD_NAV_RETURN_TO_LAUNCH {TARGET} confirmation=0"),
    (v2.MAVLink_command_long_message(1, 1, RTL, 0, NAN, 0, 0, 0, 0, 0, 0),
     f"COMMAND_LONG command=MAV_CMD_NAV_RETURN_TO_LAUNCH {TARGET} confirmation=0"),
    (v2.MAVLink_command_long_message(1, 1, RTL, 0, -0.0, 0, 0, 0, 0, 0, 0),
     f"COMMAND_LONG command=MAV_CMD_NAV_RETURN_TO_LAUNCH {TARGET} confirmation=0"),
    (v2.MAVLink_command_long_message(1, 1, RTL, 1, 1.0, 0, 0, 0, 0, 0, 0),  # unlabelled, holding something
     f"COMMAND_LONG command=MAV_CMD_NAV_RETURN_TO_LAUNCH param1=1.0 {TARGET} confirmation=1"),
    (v2.MAVLink_command_long_message(1, 1, TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 0),  # labelled "Pitch": shown at 0
     f"COMMAND_LONG command=MAV_CMD_NAV_TAKEOFF param1=0.0 {TARGET} confirmation=0"),
    (v2.MAVLink_command_long_message(1, 1, UNDEFINED, 0, 0, 0, 0, 0, 0, 0, 0),
     f"COMMAND_LONG command={UNDEFINED} {TARGET} confirmation=0"),
    (v2.MAVLink_command_long_message(1, 1, UNDEFINED, 0, 30.48, 0, 0, 0, 0, 0, 0),
     f"COMMAND_LONG command={UNDEFINED} param1=30.48 {TARGET} confirmation=0"),
    (v2.MAVLink_command_int_message(1, 1, 0, RTL, 0, 0, 0, 0, 0, 0, 0, 0, 0),
     f"COMMAND_INT command=MAV_CMD_NAV_RETURN_TO_LAUNCH {TARGET} frame=MAV_FRAME_GLOBAL"),
    (v2.MAVLink_command_int_message(1, 1, 0, RTL, 0, 0, 0, 0, 0, 0, 0, 1, -0.0),
     f"COMMAND_INT command=MAV_CMD_NAV_RETURN_TO_LAUNCH {TARGET} frame=MAV_FRAME_GLOBAL y=0.0000001"),
    (v2.MAVLink_command_int_message(1, 1, 6, REPOSITION, 0, 0, 0, 0, 0, 0, 0, 0, 0),  # labelled: shown at 0
     f"COMMAND_INT command=MAV_CMD_DO_REPOSITION {TARGET} frame=MAV_FRAME_GLOBAL_RELATIVE_ALT_INT "
     "x=0.0000000 y=0.0000000 z=0.0"),
    (v2.MAVLink_mission_item_int_message(1, 1, 3, 6, RTL, 0, 1, 0, 0, 0, 0, 0, 0, 0),
     "MISSION_ITEM_INT seq=3 command=MAV_CMD_NAV_RETURN_TO_LAUNCH frame=MAV_FRAME_GLOBAL_RELATIVE_ALT_INT"),
    (v2.MAVLink_mission_item_int_message(1, 1, 4, 6, TAKEOFF, 0, 1, 0, 0, 0, 0, 0, 0, 0),
     "MISSION_ITEM_INT seq=4 command=MAV_CMD_NAV_TAKEOFF frame=MAV_FRAME_GLOBAL_RELATIVE_ALT_INT "
     "x=0.0000000 y=0.0000000 z=0.0"),
    (v2.MAVLink_mission_item_message(1, 1, 5, 2, SET_MODE, 0, 1, 1, 0, 0, 0, 0, 2.5, NAN),
     "MISSION_ITEM seq=5 command=MAV_CMD_DO_SET_MODE frame=MAV_FRAME_MISSION y=2.5"),
]


def _capture(tmp_path: Path) -> Path:
    gcs = flows.Sender(255, 190)
    return flows.write_udp_pcap(tmp_path / "commands.pcap", [(("10.0.0.2", 14550), ("10.0.0.1", 14555),
                                                              gcs.pack(msg)) for msg, _ in CASES])


def _info(out: str) -> list[str]:
    return [m.group(1) for line in out.splitlines() if (m := re.search(r" seq +\d+ (.*)$", line))]


def test_unlabelled_params_holding_nothing_are_left_out_on_both_engines(cli: Cli, tmp_path: Path) -> None:
    path = str(_capture(tmp_path))
    native_run = cli("read", path)
    pure_run = cli("read", path, environ={"MAVSCOPE_PURE": "1"})
    assert native_run == pure_run  # stdout, stderr, status
    assert _info(pure_run.out) == [info for _, info in CASES]


def test_the_native_writer_writes_them_itself(tmp_path: Path) -> None:
    from mavscope.mavlink.dialect import load_dialect

    out, _, stats = native_summary_output(_capture(tmp_path), load_dialect(()))
    assert _info(out.decode()) == [info for _, info in CASES]
    assert stats["frames_native"] == len(CASES) and stats["records_handed_back"] == 0


# A dialect adding MAV_CMD entries (as ardupilotmega.xml does): 58001 labels param 5 only (COMMAND_INT's x),
# 58002 labels none but names param1's values by an enum; entries out of any command field's range (past
# 2**32, past 2**63) with a label, which no frame can carry (the command field is uint16; a dialect's check
# refuses negative values).
EXTRA_XML = """<?xml version="1.0"?>
<mavlink><enums>
  <enum name="TEST_PARAM_ENUM"><entry value="0" name="TEST_ZERO"/><entry value="3" name="TEST_THREE"/></enum>
  <enum name="MAV_CMD">
    <entry value="58001" name="MAV_CMD_TEST_X_ONLY"><param index="5" label="Only X">x</param></entry>
    <entry value="58002" name="MAV_CMD_TEST_NAMED"><param index="1" enum="TEST_PARAM_ENUM">no label</param></entry>
    <entry value="4294967297" name="MAV_CMD_TEST_BIG"><param index="1" label="A">a</param></entry>
    <entry value="9223372036854775809" name="MAV_CMD_TEST_HUGE"><param index="1" label="A">a</param></entry>
  </enum>
</enums></mavlink>
"""
EXTRA_CASES: list[tuple[object, str]] = [
    (v2.MAVLink_command_int_message(1, 1, 2, 58001, 0, 0, 0, 0, 0, 0, 0, 0, 0),  # x labelled, y and z not
     f"COMMAND_INT command=MAV_CMD_TEST_X_ONLY {TARGET} frame=MAV_FRAME_MISSION x=0.0000000"),
    (v2.MAVLink_command_long_message(1, 1, 58002, 0, 0, 0, 0, 0, 0, 0, 0),  # named but unlabelled: 0 left out
     f"COMMAND_LONG command=MAV_CMD_TEST_NAMED {TARGET} confirmation=0"),
    (v2.MAVLink_command_long_message(1, 1, 58002, 0, 3, 0, 0, 0, 0, 0, 0),  # holding something: its name
     f"COMMAND_LONG command=MAV_CMD_TEST_NAMED param1=TEST_THREE {TARGET} confirmation=0"),
    (v2.MAVLink_command_long_message(1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0),  # 2**32 + 1 as 32 bits is 1: no entry
     f"COMMAND_LONG command=1 {TARGET} confirmation=0"),
]


def test_a_dialects_own_commands_on_both_engines(cli: Cli, tmp_path: Path) -> None:
    xml = tmp_path / "extra.xml"
    xml.write_text(EXTRA_XML)
    gcs = flows.Sender(255, 190)
    path = flows.write_udp_pcap(tmp_path / "extra.pcap", [(("10.0.0.2", 14550), ("10.0.0.1", 14555),
                                                           gcs.pack(msg)) for msg, _ in EXTRA_CASES])
    native_run = cli("read", str(path), "--dialect", str(xml))
    assert native_run == cli("read", str(path), "--dialect", str(xml), environ={"MAVSCOPE_PURE": "1"})
    assert _info(native_run.out) == [info for _, info in EXTRA_CASES], native_run.err
    from mavscope.mavlink.dialect import load_dialect

    out, _, stats = native_summary_output(path, load_dialect([xml]))  # written in C, none handed back
    assert _info(out.decode()) == [info for _, info in EXTRA_CASES] and stats["frames_native"] == len(EXTRA_CASES)
