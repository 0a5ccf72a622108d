"""MIS_TOTAL changed by a mission upload or clear: explained, not "with no set to explain it".

The rule comes from ArduPilot's source, read apart from mavscope: AP_Mission keeps the number of mission
items, home (item 0) included, in the parameter MIS_TOTAL (`_cmd_total`): each item written past the end
raises it (`write_cmd_to_storage`, one save per item as a MISSION_ITEM(_INT) arrives), `clear()` sets it to 0
and home may be written back at once (1). So after a MISSION_COUNT of N items (mission type 0) to the vehicle
it takes values up to N; after MISSION_CLEAR_ALL of the mission (type 0 or 255, ALL) 0 or 1. The rover tlog
of ../shared shows it: a 19-item upload, then MIS_TOTAL 2, 3, ... 19 one PARAM_VALUE per item written.

The flows are built by pymavlink (tests/support/ftpflows.py); the expectations follow from what was sent.
"""

from __future__ import annotations

from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis.params import analyse
from mavscope.mavlink.dialect import Dialect
from tests.support.ftpflows import Flow, frames_of


def total(n: int) -> object:
    return v2.MAVLink_param_value_message(b"MIS_TOTAL", float(n), 4, 10, 0)  # MAV_PARAM_TYPE_INT16


def test_mission_total_follows_uploads_and_clears(tmp_path: Path, dialect: Dialect) -> None:
    flow = Flow()
    flow.send((1, 1), v2.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3))  # ArduPilot
    flow.send((2, 1), v2.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3))
    flow.send((1, 1), total(4))
    flow.send((2, 1), total(4))
    up = flow.send((255, 190), v2.MAVLink_mission_count_message(1, 1, 3, 0))
    c1 = flow.send((1, 1), total(2))  # an item written so far
    c2 = flow.send((1, 1), total(3))  # the whole upload
    c3 = flow.send((1, 1), total(7))  # more than the upload: unexplained
    c4 = flow.send((2, 1), total(3))  # another system: the upload was not to it
    flow.send((255, 190), v2.MAVLink_mission_count_message(1, 1, 5, 1))  # a fence upload: not MIS_TOTAL's
    c5 = flow.send((1, 1), total(5))
    clear = flow.send((255, 190), v2.MAVLink_mission_clear_all_message(1, 1, 255))  # every type
    c6 = flow.send((1, 1), total(0))
    log = analyse(frames_of(flow.write(tmp_path), dialect))
    got = [(e.frame, e.cause_frame, e.explanation) for e in log.timeline if e.name == "MIS_TOTAL"]
    assert got == [(c1, up, f"the items written so far of the mission upload of 3 items, MISSION_COUNT frame {up}"),
                   (c2, up, f"set by the mission upload of 3 items, MISSION_COUNT frame {up}"),
                   (c3, None, None), (c4, None, None), (c5, None, None),
                   (c6, clear, f"set by the mission clear, MISSION_CLEAR_ALL frame {clear}")]
