"""What the mission reconstruction reports: items, transfers (with their ACKs), events, and the log of a
capture. The state machine that fills them is `reconstruct.py`; the JSON and the .plan are `export.py`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from mavscope.analysis.runs import missing_runs
from mavscope.mavlink.floats import f32_shown
from mavscope.mavlink.frame import Addr
from mavscope.mavlink.semantics import finite
from mavscope.notes import Finding

MAV_MISSION_ACCEPTED = 0
MAV_MISSION_TYPE_ALL = 255
# A transfer with no frame for this long is over: every party has given up by then (ArduPilot's
# MissionItemProtocol times an upload out after 8 s, PX4's mission manager after 5 s, QGroundControl
# retries an unanswered message 5 times at 1.5 s). Frames of the same exchange after a longer silence
# belong to something else. Capture time: unknown (raw streams) means no timeout applies.
TRANSFER_TIMEOUT = 10.0

# Outcomes of a transfer (Transfer.outcome)
COMPLETE = "complete"  # the receiver accepted it and every item is in the capture
OPEN_MAX = 1024  # transfers followed at once (more: the newest unanswered but the new one closed, "evicted")
ACCEPTED_MISSING = "accepted-items-missing"  # accepted, but some items are not in the capture
UNACKNOWLEDGED = "unacknowledged"  # every item is in the capture, no MISSION_ACK closed it
NACK = "nack"  # the receiver refused it (its last ACK was an error and nothing followed)
CANCELLED = "cancelled"  # the sender of the items ended it with an ACK
ABANDONED = "abandoned"  # no ACK, items missing: a new transfer restarted it, it timed out, or the capture ends


def same(a: Addr, b: Addr) -> bool:
    """Whether two (sysid, compid) can name the same party: a target of system 0 is every system, of
    component 0 (MAV_COMP_ID_ALL) every component (the MAVLink routing rules: a message to system 0 is a
    broadcast, ArduPilot's MAVLink_routing and PX4's mavlink receiver read it as theirs), so 0/0 matches
    anyone and 1/0 any component of system 1."""
    return (a[0] == b[0] or a[0] == 0 or b[0] == 0) and (a[1] == b[1] or a[1] == 0 or b[1] == 0)


def broadcast(a: Addr) -> bool:
    """Whether a target names more than one party (system or component 0)."""
    return a[0] == 0 or a[1] == 0


@dataclass
class Item:
    seq: int
    command: int
    frame: int
    params: tuple[float, float, float, float]
    x: float  # degrees for global frames, metres otherwise
    y: float
    z: float
    current: int
    autocontinue: int
    message: str
    frames: list[int] = field(default_factory=list)

    def shown(self) -> tuple[list[object], object, object, object]:
        """(param1..4, x, y, z) as JSON, the .plan and the tables carry them: NaN and infinities as None, each
        float32 of the wire (all but MISSION_ITEM_INT's x and y, integers made degrees or metres) as the double
        of its shortest text (30.48, not 30.479999542236328: mavlink/floats.py)."""
        x, y = finite(self.x), finite(self.y)
        if self.message != "MISSION_ITEM_INT":
            x, y = f32_shown(x), f32_shown(y)
        return [f32_shown(finite(p)) for p in self.params], x, y, f32_shown(finite(self.z))

    def plan_params(self) -> list[object]:
        params, x, y, z = self.shown()
        return [*params, x, y, z]

    def content(self) -> tuple[object, ...]:
        """What the item says, comparable between copies (NaN, "unchanged" in PX4 and QGC, equals itself)."""
        return (self.command, self.frame, self.autocontinue,
                struct.pack("<7d", *self.params, self.x, self.y, self.z))


@dataclass
class Ack:
    """One MISSION_ACK of a transfer or operation."""

    sender: Addr
    result: int
    record: int
    time: float | None
    # "final" (it decided the outcome), "continued" (a NACK the exchange went on after: the parties
    # recovered), "repeated" (a NACK followed directly by another one), "late" (after the transfer ended)
    role: str = "final"


@dataclass
class Transfer:
    sender: Addr  # the system that holds the items and sends MISSION_COUNT (the GCS in an upload)
    receiver: Addr  # the system that requests them and sends the final MISSION_ACK
    mission_type: int
    count: int
    start: float | None
    order: int = 0  # creation order among transfers and events
    # the target the MISSION_COUNT (or MISSION_WRITE_PARTIAL_LIST) named: the receiver is whoever answered
    # it, which a broadcast target (system or component 0) leaves open until someone does
    addressed: Addr | None = None
    first: int = 0  # the first seq transferred: start_index of a MISSION_WRITE_PARTIAL_LIST, else 0
    partial: bool = False  # a MISSION_WRITE_PARTIAL_LIST upload (items first..count-1 of the mission)
    opened: int = 0  # how many of `frames` opened it (its COUNT, copies sent before an answer, a REQUEST_LIST)
    frames: list[int] = field(default_factory=list)
    direction: str = ""  # "upload" (to the vehicle), "download" (from it), "unknown"
    direction_basis: str = ""  # "request-list", "heartbeat", "component-id", "none"
    items: dict[int, Item] = field(default_factory=dict)
    requests: list[int] = field(default_factory=list)
    resent: dict[int, int] = field(default_factory=dict)  # seq -> extra copies
    resent_changed: set[int] = field(default_factory=set)  # seqs whose copies differ in content
    count_resent: int = 0
    duplicates: list[int] = field(default_factory=list)  # byte copies (same MAVLink seq) ignored
    late_frames: list[int] = field(default_factory=list)  # frames of the exchange after it ended
    acks: list[Ack] = field(default_factory=list)
    pending: Ack | None = None  # a NACK not (yet) followed by anything
    max_request: int = -1
    last: float | None = None  # time of the last frame of the transfer
    end: float | None = None
    result: int | None = None
    closed: str = ""  # "ack", "nack", "cancelled", "restarted", "timeout", "end", "evicted"
    outcome: str = ""
    complete: bool = False
    reason: str = ""
    receiver_silent: bool = False  # the receiver sent no frame at all in the capture

    @property
    def missing(self) -> list[list[int]]:
        """[[first, last], ...]: the runs of seqs `first`..`count`-1 with no item in the capture."""
        return [[max(a, self.first), b] for a, b in missing_runs(self.items, self.count) if b >= self.first]

    @property
    def missing_count(self) -> int:
        return max(0, self.count - self.first) - sum(1 for s in self.items if self.first <= s < self.count)

    @property
    def answered(self) -> bool:
        """Whether the receiver has answered (a request, an ACK) or the sender gone on (an item)."""
        return bool(self.requests or self.items or self.acks)

    @property
    def nacks(self) -> list[Ack]:
        return [a for a in self.acks if a.result != MAV_MISSION_ACCEPTED]

    def touch(self, record: int, time: float | None) -> None:
        self.frames.append(record)
        if time is not None:
            self.last = self.end = time

    def close(self, how: str) -> None:
        """End the transfer: `how` is "ack" (the receiver accepted), "restarted", "timeout" or "end". A NACK
        that nothing followed decides the outcome whichever way the transfer ends."""
        if self.closed:
            return
        ack = self.pending
        if ack is not None and how != "ack":
            ack.role = "final"
            self.result = ack.result
            how = "nack" if same(ack.sender, self.receiver) and ack.sender != self.sender else "cancelled"
            self.end = ack.time if ack.time is not None else self.end
        self.pending = None
        self.closed = how
        missing = bool(self.missing)
        if how == "ack":
            self.outcome = ACCEPTED_MISSING if missing else COMPLETE
        elif how in ("nack", "cancelled"):
            self.outcome = NACK if how == "nack" else CANCELLED
        else:
            self.outcome = ABANDONED if missing else UNACKNOWLEDGED
        self.complete = self.outcome == COMPLETE


@dataclass
class Event:
    """A mission operation that is not an item transfer: MISSION_CLEAR_ALL (answered by a MISSION_ACK),
    MISSION_SET_CURRENT (answered by MISSION_CURRENT), a MISSION_REQUEST_LIST no MISSION_COUNT answered,
    a MISSION_ACK that answers nothing, or mission frames outside any transfer ("orphan")."""

    kind: str  # "clear-all", "set-current", "request-list", "unmatched-ack", "orphan"
    sender: Addr
    target: Addr  # clear-all: the party that answered, once one did
    mission_type: int
    time: float | None
    order: int
    frames: list[int] = field(default_factory=list)
    ack: Ack | None = None  # clear-all, request-list: the answer; unmatched-ack: the ACK itself
    seq: int | None = None  # set-current: the item asked for
    reported: int | None = None  # set-current: the seq of MISSION_CURRENT after it
    reply_frame: int | None = None  # set-current: that MISSION_CURRENT
    confirmed: bool | None = None  # set-current: MISSION_CURRENT reported the seq asked for
    messages: dict[str, int] = field(default_factory=dict)  # orphan: message name -> frames
    seqs: list[int] = field(default_factory=list)  # orphan: item seqs requested or sent
    last: float | None = None
    repeats: list[Ack] = field(default_factory=list)  # clear-all: the same answer again (old ArduPilot sent it 3 times)
    answered_by: list[Addr] = field(default_factory=list)  # request-list to a broadcast target: who sent a COUNT
    addressed: Addr | None = None  # clear-all, request-list: the target the message named


@dataclass
class MissionLog:
    """Everything the reconstruction found in a capture."""

    transfers: list[Transfer]
    events: list[Event]
    heartbeats: dict[Addr, tuple[int, int]]  # sender -> (MAV_TYPE, MAV_AUTOPILOT) of its last HEARTBEAT
    homes: dict[int, tuple[float, float, float]]  # sysid -> last HOME_POSITION (deg, deg, m AMSL)
    duplicates: int = 0  # mission frames ignored as byte copies of an earlier one
    given_up: Finding | None = None  # the `capacity` finding of what the tracker's bounds gave up

    def heartbeat_of(self, addr: Addr) -> tuple[int, int] | None:
        return heartbeat_of(self.heartbeats, addr)


def heartbeat_of(heartbeats: dict[Addr, tuple[int, int]], addr: Addr) -> tuple[int, int] | None:
    """(MAV_TYPE, MAV_AUTOPILOT) of `addr`'s last HEARTBEAT, else of a vehicle component of its system."""
    hb = heartbeats.get(addr)
    if hb is not None:
        return hb
    for (sysid, _), value in heartbeats.items():
        if sysid == addr[0] and role(value) == "vehicle":
            return value
    return None


# MAV_TYPE values of systems that are not vehicles (common.xml): GCS 6, ONBOARD_CONTROLLER 18, GIMBAL 26,
# ADSB 27, CAMERA 30, CHARGING_STATION 31, FLARM 32, SERVO 33, ODID 34, BATTERY 36, PARACHUTE 37, LOG 38,
# OSD 39, IMU 40, GPS 41, WINCH 42, ILLUMINATOR 44.
NON_VEHICLE_TYPES = frozenset({6, 18, 26, 27, 30, 31, 32, 33, 34, 36, 37, 38, 39, 40, 41, 42, 44})
MAV_TYPE_GCS = 6
MAV_AUTOPILOT_INVALID = 8


def role(heartbeat: tuple[int, int]) -> str:
    """"gcs", "vehicle" or "other" by a HEARTBEAT's (MAV_TYPE, MAV_AUTOPILOT)."""
    mav_type, autopilot = heartbeat
    if mav_type == MAV_TYPE_GCS:
        return "gcs"
    if mav_type not in NON_VEHICLE_TYPES and autopilot != MAV_AUTOPILOT_INVALID:
        return "vehicle"
    return "other"
