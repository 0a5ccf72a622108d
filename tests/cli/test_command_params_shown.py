"""`commands` shows a command's parameters as the dialect labels them (issue 35, item 15).

The rule: a parameter the MAV_CMD entry labels (`<param index=N label=...>`) is shown with its label, whatever
its value; one it leaves unlabelled (no label, an empty one, or a reserved param) is left out when it is 0
(or NaN, the protocol's "no value", which the JSON writes as null), else shown as paramN (COMMAND_INT's x, y,
z are params 5, 6, 7). Expected labels come from pymavlink's own parser (mavparse) reading common.xml and
ardupilotmega.xml, not from mavscope's dialect; the values are the frame's (the JSON document's, whose
decoding other tests check against pymavlink).
"""

from __future__ import annotations

import io
import json
import math
import re
from functools import cache
from pathlib import Path

import pymavlink
import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2
from pymavlink.generator import mavparse

from mavscope.cli import Env, main
from tests.conftest import CAPTURES, REAL_CAPTURES
from tests.support.flows import T0, Sender, write_tlog

XML = Path(pymavlink.__file__).parent / "dialects" / "v20"
ITEM = re.compile(r"^(.*?) ([^ ]+(?: \| [^ ]+)*)$")  # NAME VALUE, the shortest name a value can follow
INT_FIELDS = {"x": 5, "y": 6, "z": 7}  # COMMAND_INT: param5..7 travel as x, y, z


@cache
def labels() -> dict[int, dict[int, str]]:
    """MAV_CMD value -> {param index: label} of the labelled, not reserved params (mavparse's reading)."""
    out: dict[int, dict[int, str]] = {}
    for name in ("common.xml", "ardupilotmega.xml"):
        xml = mavparse.MAVXML(str(XML / name), wire_protocol_version="2.0")
        for enum in xml.enum:
            if enum.name != "MAV_CMD":
                continue
            for entry in enum.entry:
                out[int(entry.value)] = {int(p.index): p.label.strip() for p in entry.param
                                         if (p.label or "").strip() and not p.reserved}
    return out


def expected_names(command: int, message: str, params: dict[str, object]) -> list[str]:
    """The parameter names the row shows, in the frame's field order."""
    known = labels().get(command, {})
    names = []
    for key, value in params.items():
        if key.startswith("param"):
            index = int(key[5:])
        elif message == "COMMAND_INT" and key in INT_FIELDS:
            index = INT_FIELDS[key]
        else:  # not a parameter (COMMAND_INT's frame, current, autocontinue): shown when not 0
            if value not in (0, None) and key != "confirmation":
                names.append(key)
            continue
        if known.get(index):
            names.append(known[index])
        elif value is not None and not (isinstance(value, float) and math.isnan(value)) and value != 0:
            names.append(f"param{index}")
    return names


def _run(*argv: str) -> str:
    out, err = io.StringIO(), io.StringIO()
    assert main(list(argv), Env(stdout=out, stderr=err, environ={})) == 0, err.getvalue()
    return out.getvalue()


def _rows(text: str) -> dict[str, list[str]]:
    """First frame -> the names in the parameters cell (each item "NAME VALUE"; a value holds no space but in
    a bitmask's "A | B")."""
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.split("│")]
        if len(cells) > 7 and cells[1].isdigit():
            items = cells[6].split(", ") if cells[6] else []
            rows[cells[1]] = [m.group(1) for m in (ITEM.match(item) for item in items) if m]
            assert len(rows[cells[1]]) == len(items), cells[6]
    return rows


def check(capture: str) -> int:
    doc = json.loads(_run("commands", capture, "--json"))
    rows = _rows(_run("commands", capture))
    for c in doc["commands"]:
        frame = str(c["frames"][0])
        assert rows[frame] == expected_names(c["command_id"], c["message"], c["params"]), (capture, frame, c)
    return len(doc["commands"])


def test_built_commands(tmp_path: Path) -> None:
    """By hand: NAV_RETURN_TO_LAUNCH (20) labels none of its params, so param3 = 5 shows as param3 and the
    zeros not at all; COMPONENT_ARM_DISARM (400) labels Arm and Force, shown at 0; DO_SET_MODE (176) sent as
    COMMAND_INT labels params 1-3 (Mode, Custom Mode, Custom Submode): x = 7 unlabelled shows as param5, y
    and z at 0 do not; REQUEST_MESSAGE (512) with an unlabelled param NaN: left out."""
    gcs = Sender(255, 190)
    msgs = [v2.MAVLink_command_long_message(1, 1, 20, 0, 0, 0, 5.0, 0, 0, 0, 0),
            v2.MAVLink_command_long_message(1, 1, 400, 0, 0, 0, 0, 0, 0, 0, 0),
            v2.MAVLink_command_int_message(1, 1, 0, 176, 0, 0, 1, 4, 0, 0, 7, 0, 0),
            v2.MAVLink_command_long_message(1, 1, 512, 0, 33, 0, 0, 0, 0, 0, float("nan"))]
    path = write_tlog(tmp_path, [(T0 + i, gcs.pack(m)) for i, m in enumerate(msgs)])
    rows = _rows(_run("commands", path))
    assert rows["1"] == ["param3"]
    assert rows["2"] == ["Arm", "Force"]
    assert rows["3"] == ["Mode", "Custom Mode", "Custom Submode", "param5"]
    assert rows["4"][0] == "Message ID" and "param7" not in rows["4"]
    assert check(path) == 4


@pytest.mark.parametrize("capture", sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".tlog")),
                         ids=lambda p: p.name)
def test_bundled_captures(capture: Path) -> None:
    check(str(capture))


def test_real_captures(real_captures: Path) -> None:
    total = sum(check(str(p)) for p in sorted(REAL_CAPTURES.iterdir()) if p.suffix != ".md")
    assert total > 0
