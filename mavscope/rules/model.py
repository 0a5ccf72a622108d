"""A detection rule as data (docs/rules.md): what it matches (a display filter), under which conditions, and
what it tells the analyst. Records only: the loader (loader.py) makes them from TOML, the engine (engine.py)
runs them."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from mavscope.notes import Severity


class Per(str, Enum):
    """What a threshold counts matches per."""

    SENDER = "sender"  # (system id, component id)
    LINK = "link"  # the frame's link: its pair of endpoints (a tlog's or raw stream's one link)


class SenderState(str, Enum):
    """The `sender` condition: the frame's place among its sender's frames of the same message."""

    FIRST = "first"  # the sender's first frame of this message in the capture
    NEW = "new"  # that, while another sender had sent the message before


@dataclass(frozen=True, slots=True)
class Threshold:
    """At least `count` matches within `window` seconds (capture time), counted per sender or per link."""

    count: int
    window: float
    per: Per


@dataclass(frozen=True, slots=True)
class Conditions:
    """What must hold besides the filter (None: not asked). The vehicle is the frame's target system (its
    `target_system`, or MANUAL_CONTROL's `target`), else the sender's system when it is a vehicle, else any
    vehicle heard."""

    armed: bool | None = None  # the vehicle's last HEARTBEAT says armed (False: says disarmed)
    in_flight: bool | None = None  # armed and in the air (docs/rules.md, "Vehicle state")
    modes: tuple[str, ...] = ()  # the vehicle's flight mode is one of these (or a sub mode: AUTO -> AUTO.MISSION)
    unsigned: bool | None = None  # the frame is not signed (or its signature failed) and its link never signed
    sender: SenderState | None = None
    signature_ahead: float | None = None  # the frame's signature time is this many seconds past its capture time

    @property
    def vehicle(self) -> bool:
        return self.armed is not None or self.in_flight is not None or bool(self.modes)


@dataclass(frozen=True, slots=True)
class Rule:
    """One rule, with where it was read (file and line of its `[[rule]]`, for errors and `rules list`)."""

    id: str
    title: str
    severity: Severity
    filter: str
    references: tuple[str, ...]
    explanation: str
    remediation: str
    when: Conditions
    threshold: Threshold | None
    source: str
    line: int
    filter_line: int  # the line of its `filter =` (where a filter error points)
