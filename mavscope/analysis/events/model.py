"""What the flight's story is made of: `Event` records, and the `EventSource` protocol that yields them.

An event source is a small accumulator: `add(frame, fields)` once per frame in capture order returns the
events that frame completed, `finish()` the ones still open at the end. Every frame with a good CRC
reaches every source; `wants` only names the messages whose payload the log decodes for it (`fields`,
else None), once per frame for all the sources that want it. A source built on another analysis's
tracker, which takes frames and decodes what it reads, lists those messages in `wants` and hands the
tracker `fields` (`tracker.feed(frame, fields)`), so nothing is decoded twice; what a tracker reads from
the bytes (MAVLink FTP) it does not want. A source keeps bounded state. Events
may be completed later than the frame they are dated by (a command when its ACK comes, a link loss when
the sender is heard again): the log sorts them by frame.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Protocol

from mavscope.mavlink.frame import Addr, Frame

Fields = dict[str, object]

# Kinds of events (JSON `kind`), in the order docs/analysis.md lists them.
VEHICLE = "vehicle"  # a vehicle's first HEARTBEAT, or its type changing
ARMING = "arming"  # armed / disarmed
MODE = "mode"  # flight mode changed
FAILSAFE = "failsafe"  # MAV_STATE CRITICAL / EMERGENCY / FLIGHT_TERMINATION entered or left; failsafe texts
REBOOT = "reboot"  # the boot clock went back
MISSION = "mission"  # transfers, clear, set-current; MISSION_CURRENT changes, MISSION_ITEM_REACHED
STATUSTEXT = "statustext"
COMMAND = "command"  # COMMAND_LONG / COMMAND_INT with their ACK, SET_MODE
PARAM = "param"  # the parameter timeline: sets with their answer, changes and what explains them
FILE = "file"  # objects moved (FTP files and listings, logs, images), FTP operations with their answer
SIGNING = "signing"  # signing starts, a signer sends unsigned, SETUP_SIGNING, bad or replayed signatures
LINK = "link"  # a sender falls silent, and is heard again
KINDS = (VEHICLE, ARMING, MODE, FAILSAFE, REBOOT, MISSION, STATUSTEXT, COMMAND, PARAM, FILE, SIGNING, LINK)


@dataclass(frozen=True, slots=True)
class Event:
    """One thing that happened: when (capture time and the frame that shows it), what kind, who, a
    sentence, and the kind's data."""

    time: float | None
    frame: int  # capture record number of the frame the event is dated by
    kind: str
    sender: Addr  # the system the event is about or came from (JSON `from`)
    text: str
    target: Addr | None = None  # who it was addressed to (JSON `to`)
    details: dict[str, object] = field(default_factory=dict)

    def to_json(self) -> dict[str, object]:
        return {"time": self.time, "frame": self.frame, "kind": self.kind, "from": list(self.sender),
                "to": None if self.target is None else list(self.target), "text": self.text,
                "details": self.details}


class EventSource(Protocol):
    """An accumulator yielding events (see the module docstring)."""

    wants: frozenset[str]  # message names whose payload `add` gets decoded (it gets every frame)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]: ...

    def finish(self) -> Iterable[Event]: ...


def addr(a: Addr) -> str:
    return f"{a[0]}/{a[1]}"


def at(f: Frame, kind: str, text: str, target: Addr | None = None, **details: object) -> Event:
    """An event dated by frame `f`, from its sender."""
    return Event(f.time, f.record, kind, (f.sysid, f.compid), text, target, details)
