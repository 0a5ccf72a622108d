"""Stream-rate parameters that REQUEST_DATA_STREAM sets: the explanation of their changes.

ArduPilot stores the rate a REQUEST_DATA_STREAM asks for in a parameter (`GCS_MAVLINK::
handle_request_data_stream`, libraries/GCS_MAVLink/GCS_Param.cpp): start_stop 0 stores 0, 1 stores
req_message_rate, any other value is ignored. The parameter is the stream's member of the stream-rate group
of the channel the request arrived on (GCS_MAVLink_Parameters.cpp: `_RAW_SENS`, `_EXT_STAT`, `_RC_CHAN`,
`_RAW_CTRL`, `_POSITION`, `_EXTRA1`, `_EXTRA2`, `_EXTRA3`, `_PARAMS`, `_ADSB`), named `SRn_` with n the
channel from 0 (the vehicles' Parameters.cpp) or, since the group moved under GCS (GCS.cpp), `MAVn_` with n
from 1. MAV_DATA_STREAM_ALL sets every stream but `_PARAMS`. A capture does not show the channel, so a
request explains a change of the stream's parameter in any group of the system it addresses.

A value read over FTP in a param.pck may predate a request made while the file was read (ArduPilot reads
the values as it sends the file): a value other than the one requested there is explained as such.

State is bounded: the last `KEPT` requests per (system, stream), for at most `MAX_KEYS` of them.
"""

from __future__ import annotations

import re
from collections import deque
from dataclasses import dataclass

from mavscope.analysis.params.values import Value, same, value_text

# MAV_DATA_STREAM (common.xml) -> the member of the stream-rate group it sets
STREAMS = {1: "RAW_SENS", 2: "EXT_STAT", 3: "RC_CHAN", 4: "RAW_CTRL", 6: "POSITION", 10: "EXTRA1", 11: "EXTRA2",
           12: "EXTRA3"}
MAV_DATA_STREAM_ALL = 0
ALL = (*STREAMS.values(), "ADSB")  # every stream but PARAMS
PARAM = re.compile(r"^(?:SR\d+|MAV\d+)_(RAW_SENS|EXT_STAT|RC_CHAN|RAW_CTRL|POSITION|EXTRA1|EXTRA2|EXTRA3|ADSB)$")
KEPT = 8
MAX_KEYS = 4096
MESSAGE = "REQUEST_DATA_STREAM"


@dataclass(frozen=True, slots=True)
class _Request:
    frame: int
    component: int  # target_component (0: every component)
    value: int


@dataclass(frozen=True, slots=True)
class Cause:
    """What explains a change: the request's frame and the words that say how."""

    frame: int
    text: str


def _int(fields: dict[str, object], name: str) -> int:
    v = fields.get(name, 0)
    return v if isinstance(v, int) else 0


class StreamRequests:
    """The REQUEST_DATA_STREAMs of a capture (`feed`), and the change of a stream-rate parameter each
    explains (`explain`)."""

    def __init__(self) -> None:
        self.requests: dict[tuple[int, str], deque[_Request]] = {}
        self.unfollowed = 0  # requests of (system, stream) pairs beyond the first MAX_KEYS, not remembered

    def feed(self, record: int, fields: dict[str, object]) -> None:
        start_stop = _int(fields, "start_stop")
        if start_stop not in (0, 1):
            return  # ArduPilot ignores it
        rate = _int(fields, "req_message_rate")
        value = 0 if start_stop == 0 else (rate if rate < 32768 else rate - 65536)  # stored in an int16
        stream = _int(fields, "req_stream_id")
        names = ALL if stream == MAV_DATA_STREAM_ALL else (STREAMS[stream],) if stream in STREAMS else ()
        req = _Request(record, _int(fields, "target_component"), value)
        for name in names:
            key = (_int(fields, "target_system"), name)
            kept = self.requests.get(key)
            if kept is None:
                if len(self.requests) >= MAX_KEYS:  # (the first kept: a flood cannot flush them)
                    self.unfollowed += 1
                    return
                kept = self.requests[key] = deque(maxlen=KEPT)
            kept.append(req)

    def explain(self, addr: tuple[int, int], name: str, value: Value, record: int,
                read_from: int | None = None) -> Cause | None:
        """The request that explains component `addr` reporting `name` = `value` in frame `record` (a
        param.pck read over FTP from frame `read_from`), or None."""
        m = PARAM.match(name)
        if m is None:
            return None
        stream = m.group(1)
        mine = [r for key in ((addr[0], stream), (0, stream)) for r in self.requests.get(key, ())
                if r.frame < record and r.component in (0, addr[1])]
        mine.sort(key=lambda r: r.frame)
        for r in reversed(mine):
            if same(value, r.value):
                return Cause(r.frame, f"set by {MESSAGE} frame {r.frame}")
        if read_from is not None:
            during = [r for r in mine if r.frame >= read_from]
            if during:
                r = during[-1]
                return Cause(r.frame, f"the value from before {MESSAGE} frame {r.frame} set "
                                      f"{value_text(r.value)} (the file was read across it)")
        return None
