"""Mission reconstruction: every mission, geofence and rally point transfer of a capture (MISSION_COUNT,
MISSION_REQUEST(_INT), MISSION_ITEM(_INT), MISSION_ACK, both directions), the other mission operations
(MISSION_CLEAR_ALL, MISSION_SET_CURRENT), and a QGroundControl .plan of what was transferred.

`reconstruct.py` is the state machine (bounded state over frames in capture order), `model.py` what it
reports, `describe.py` the sentences, `export.py` the JSON and the .plan.
"""

from mavscope.analysis.mission.describe import event_text, reason
from mavscope.analysis.mission.export import (
    PlanExport,
    event_json,
    item_json,
    log_json,
    pick,
    to_plan,
    transfer_json,
)
from mavscope.analysis.mission.model import (
    TRANSFER_TIMEOUT,
    Ack,
    Event,
    Item,
    MissionLog,
    Transfer,
)
from mavscope.analysis.mission.reconstruct import (
    MISSION_MESSAGES,
    TRACKED_MESSAGES,
    MissionTracker,
    analyse,
    reconstruct,
)

__all__ = [
    "MISSION_MESSAGES", "TRACKED_MESSAGES", "TRANSFER_TIMEOUT", "Ack", "Event", "Item", "MissionLog",
    "MissionTracker", "PlanExport", "Transfer", "analyse", "event_json", "event_text", "item_json", "log_json",
    "pick", "reason", "reconstruct", "to_plan", "transfer_json",
]
