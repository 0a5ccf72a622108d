"""A capture with far more rows than the page shows: the page stays small (well under 5 MB), says how many
rows it left out and names the command that lists them all, and the JSON keeps every one the analyses keep.
The capture is built here: 12,000 STATUSTEXTs, 3,000 parameter values, 3,000 commands and 2,000 positions."""

from __future__ import annotations

import json
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis.events import FIRST_KEPT, LAST_KEPT
from tests.conftest import Cli
from tests.support.builders import heartbeat_msg
from tests.support.flows import command_long
from tests.support.ftpflows import GCS, VEHICLE, Flow

MAX_PAGE = 5 * 1024 * 1024


def test_a_long_capture_makes_a_short_page(cli: Cli, tmp_path: Path) -> None:
    flow = Flow()
    flow.send(VEHICLE, heartbeat_msg(2, 3, 1, 0, 3))
    flow.send(GCS, heartbeat_msg(6, 8))
    for i in range(12_000):
        flow.send(VEHICLE, v2.MAVLink_statustext_message(6, f"text {i} <b>&".encode()), dt=0.001)
        if i % 4 == 0:
            flow.send(VEHICLE, v2.MAVLink_param_value_message(b"SOME_PARAM", float(i), 9, 1, 0), dt=0.001)
            flow.send(GCS, command_long(511, float(i)), dt=0.001)
        if i % 6 == 0:
            flow.send(VEHICLE, v2.MAVLink_global_position_int_message(i, 473_977_420 + i, 85_455_940, 500_000, i,
                                                                       0, 0, 0, 0), dt=0.001)
    cap = flow.write(tmp_path, "long.tlog")
    status, _, err = cli("report", str(cap), "-o", str(tmp_path / "r.html"), "--json", str(tmp_path / "r.json"))
    assert status == 0, err
    page = (tmp_path / "r.html").read_text(encoding="utf-8")
    doc = json.loads((tmp_path / "r.json").read_text())
    assert len(page.encode()) < MAX_PAGE
    story = doc["inputs"][0]["events"]
    events = story["events"]
    # the JSON has every one the story keeps (its bound: the first and the last of each kind and sender) and
    # counts all 12,000
    assert len([e for e in events if e["kind"] == "statustext"]) == FIRST_KEPT + LAST_KEPT
    assert story["counts"]["statustext"] == 12_000 and story["dropped"]["statustext"] == 12_000 - FIRST_KEPT - LAST_KEPT
    assert "7000 statustext events were not listed" in page
    assert page.count('<tr class="ev-') == 400  # the page the first 400...
    assert f"{len(events) - 400} more events: <code>mavscope events {cap} --json</code> lists them all" in page
    changes = doc["inputs"][0]["params"]["changes"]
    assert len(changes) == 2_999  # one PARAM_VALUE in four of the texts: the first its value, each later one a change
    assert f"{len(changes) - 300} more: <code>mavscope params {cap} --json</code>" in page
