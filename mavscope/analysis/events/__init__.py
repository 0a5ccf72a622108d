"""The flight's story in one chronological list: arming, modes, mission progress, STATUSTEXT, failsafes,
commands with their ACK, parameter changes, file transfers, signing, link loss and recovery.

`model.py` is the `Event` record and the `EventSource` protocol (an accumulator yielding events); the
sources are `vehicle.py` (HEARTBEAT state, reboots, mission progress, STATUSTEXT), `traffic.py`
(commands, missions), `records.py` (the parameter timeline and the objects and FTP operations of
`mavscope params` and `mavscope objects`) and `links.py` (signing, link loss); `log.py` runs them over a
capture in one pass (`EventLog`, `story`). Plugging in another source: add its factory to
`log.SOURCES` (or pass a list to `EventLog`).
"""

from mavscope.analysis.events.log import (
    FIRST_KEPT,
    LAST_KEPT,
    MAX_CHATTER,
    MAX_EVENTS,
    SOURCES,
    EventList,
    EventLog,
    SourceFactory,
    story,
)
from mavscope.analysis.events.model import KINDS, Event, EventSource

__all__ = ["FIRST_KEPT", "KINDS", "LAST_KEPT", "MAX_CHATTER", "MAX_EVENTS", "SOURCES", "Event", "EventList", "EventLog",
           "EventSource", "SourceFactory", "story"]
