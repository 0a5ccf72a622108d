"""MIS_TOTAL, which ArduPilot sets itself when a mission is uploaded or cleared: the explanation of its changes.

ArduPilot keeps the number of mission items (home, item 0, included) in the parameter MIS_TOTAL
(AP_Mission `_cmd_total`, saved by each item written and by `clear()`/`truncate()`): a mission upload
(MISSION_COUNT of mission type 0, the only type in MAVLink 1) of N items takes it through the items written
to N; a MISSION_CLEAR_ALL of the mission (type 0, or MAV_MISSION_TYPE_ALL) leaves 0, or 1 where the vehicle
keeps home. The real plane and rover tlogs we hold show it: Mission Planner's upload of 0 items, then
`MIS_TOTAL` 4 -> 0 two frames later; the rover's upload of 19 items, then MIS_TOTAL 4, 5, ... 19 as they
are written. A change of MIS_TOTAL on a system is explained by the last such request to it before the
change, when the value is one that request takes it to.

State is bounded: the last request per system.
"""

from __future__ import annotations

import math

from mavscope.analysis.objects.model import int_field
from mavscope.analysis.params.streams import Cause
from mavscope.analysis.params.values import Value

PARAM = "MIS_TOTAL"
MISSION, ALL = 0, 255  # MAV_MISSION_TYPE_MISSION, MAV_MISSION_TYPE_ALL
MESSAGES = frozenset({"MISSION_COUNT", "MISSION_CLEAR_ALL"})


class MissionRequests:
    """The mission uploads and clears of a capture (`feed`), and the MIS_TOTAL change each explains."""

    def __init__(self) -> None:
        self.last: dict[int, tuple[int, str, int]] = {}  # system -> (frame, message, the largest value it leaves)

    def feed(self, record: int, message: str, fields: dict[str, object]) -> None:
        mtype = int_field(fields, "mission_type")  # 0, the mission, where MAVLink 1 has no such field
        if message == "MISSION_COUNT" and mtype == MISSION:
            self.last[int_field(fields, "target_system")] = (record, message, int_field(fields, "count"))
        elif message == "MISSION_CLEAR_ALL" and mtype in (MISSION, ALL):
            self.last[int_field(fields, "target_system")] = (record, message, 1)

    def explain(self, addr: tuple[int, int], name: str, value: Value, record: int) -> Cause | None:
        """The upload or clear that explains system `addr[0]` reporting MIS_TOTAL = `value` in frame
        `record`, or None."""
        if name != PARAM:
            return None
        last = self.last.get(addr[0])
        if last is None or last[0] >= record or not _whole(value, last[2]):
            return None
        frame, message, top = last
        if message == "MISSION_CLEAR_ALL":
            return Cause(frame, f"set by the mission clear, {message} frame {frame}")
        if value == top:
            return Cause(frame, f"set by the mission upload of {top} items, {message} frame {frame}")
        return Cause(frame, f"the items written so far of the mission upload of {top} items, {message} frame {frame}")


def _whole(value: Value, top: int) -> bool:
    """Whether `value` is a whole number 0..top (a count: exact as a float32 too, for any count of 16 bits)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            and value == int(value) and 0 <= value <= top)
