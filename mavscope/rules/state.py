"""The state the rules' conditions read, kept as frames go by (bounded, docs/rules.md, "Bounds").

- Vehicle state: each system's last vehicle HEARTBEAT from the analyses' `Systems` (mavscope.analysis.vehicles:
  armed, flight mode by autopilot, system status; the audit's event log's own when it runs one, so the
  HEARTBEATs are read once), and whether it is in the air as the expert's control detector judges it
  (mavscope.analysis.control's thresholds): EXTENDED_SYS_STATE's landed state IN_AIR or TAKEOFF seen within
  STATE_FRESH_S, else GLOBAL_POSITION_INT.relative_alt above ALT_FLYING_M within that time, else, with
  neither, armed and MAV_STATE_ACTIVE.
- Signing per link: the links (a frame's pair of endpoints, or its transport for a tlog or raw stream) that
  carried a frame whose signature the security stage did not reject (verdict valid or no-key).
- First senders: per message, the senders heard sending it.
"""

from __future__ import annotations

from collections.abc import Hashable

from mavscope.analysis.control import ALT_FLYING_M, MAV_LANDED_STATE_IN_AIR, MAV_LANDED_STATE_TAKEOFF, STATE_FRESH_S
from mavscope.analysis.vehicles import MAX_SENDERS, Heartbeat, Systems
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame, SignatureStatus
from mavscope.notes import GivenUp

Fields = dict[str, object]
MAV_STATE_ACTIVE = 4
HEARTBEAT, GLOBAL_POSITION_INT, EXTENDED_SYS_STATE = 0, 33, 245
AIRBORNE = frozenset({MAV_LANDED_STATE_IN_AIR, MAV_LANDED_STATE_TAKEOFF})
SIGNED = frozenset({SignatureStatus.VALID, SignatureStatus.NO_KEY, None})  # not rejected by the security stage
MAX_LINKS = 1 << 16  # links remembered as signing
MAX_FIRST = 1 << 16  # (message, sender) pairs remembered per message watched


def link_of(f: Frame) -> Hashable:
    """A frame's link, the same both ways: its two endpoints (its transport where it has none)."""
    if f.src is None or f.dst is None:
        return f.transport
    return frozenset((f.src, f.dst))


def signed(f: Frame) -> bool:
    """Whether the frame carries a signature the security stage did not reject."""
    if f.signature is None:
        return False
    sec = f.security
    return sec is None or sec.signature_status in SIGNED


class VehicleState:
    """What the conditions `armed`, `in_flight` and `mode` read, per system id."""

    def __init__(self, dialect: Dialect, systems: Systems | None = None) -> None:
        self.feeds = systems is None  # its own Systems: it reads the HEARTBEATs itself
        self.systems = Systems(dialect) if systems is None else systems
        self.landed: dict[int, tuple[int, float | None]] = {}  # sysid -> (MAV_LANDED_STATE, capture time)
        self.alt: dict[int, tuple[float, float | None]] = {}  # sysid -> (relative altitude m, capture time)

    def see(self, f: Frame, fields: Fields) -> None:
        """A HEARTBEAT, EXTENDED_SYS_STATE or GLOBAL_POSITION_INT (decoded `fields`)."""
        if f.msgid == HEARTBEAT:
            if self.feeds:
                self.systems.see(f, fields)
            return
        if f.sysid not in self.systems.vehicles:
            return
        if f.msgid == EXTENDED_SYS_STATE:
            state = fields.get("landed_state")
            if isinstance(state, int):
                self.landed[f.sysid] = (state, f.time)
        elif f.msgid == GLOBAL_POSITION_INT:
            alt = fields.get("relative_alt")
            if isinstance(alt, int):
                self.alt[f.sysid] = (alt / 1000, f.time)

    def heartbeat(self, sysid: int) -> Heartbeat | None:
        return self.systems.vehicle(sysid)

    def in_flight(self, sysid: int, now: float | None) -> bool:
        hb = self.systems.vehicle(sysid)
        if hb is None or not hb.armed:
            return False

        def fresh(t: float | None) -> bool:
            return t is None or now is None or now - t <= STATE_FRESH_S

        landed = self.landed.get(sysid)
        if landed is not None and fresh(landed[1]):
            return landed[0] in AIRBORNE
        alt = self.alt.get(sysid)
        if alt is not None and fresh(alt[1]):
            return alt[0] > ALT_FLYING_M
        return hb.system_status == MAV_STATE_ACTIVE

    def mode(self, sysid: int) -> str | None:
        hb = self.systems.vehicle(sysid)
        return None if hb is None else self.systems.mode_name(hb)

    def vehicles(self) -> list[int]:
        return list(self.systems.vehicles)


class SigningLinks:
    """The links seen signing (bounded: past MAX_LINKS a new one is not remembered, said as `capacity`)."""

    def __init__(self) -> None:
        self.links: set[Hashable] = set()
        self.given_up = GivenUp(f"rules: links seen signing ({MAX_LINKS:,} links)", "links")

    def see(self, f: Frame) -> None:
        if f.signature is None or not signed(f):
            return
        link = link_of(f)
        if link in self.links:
            return
        if len(self.links) >= MAX_LINKS:
            self.given_up.add("a signing link not remembered: its unsigned frames may be taken for an unsigned "
                              "link's", record=f.record)
            return
        self.links.add(link)

    def unsigned(self, f: Frame) -> bool:
        """The frame is not signed (or its signature was rejected) and its link never carried a signed frame."""
        return not signed(f) and link_of(f) not in self.links


class FirstSenders:
    """Per watched message, the senders heard sending it (bounded per message: MAX_FIRST senders, each one
    the bound leaves out said as `capacity`, and taken as not new: no finding from a bound)."""

    def __init__(self, messages: frozenset[int]) -> None:
        self.seen: dict[int, set[int]] = {m: set() for m in messages}
        self.given_up = GivenUp(f"rules: senders per message ({MAX_FIRST:,} senders)", "senders")

    def see(self, f: Frame) -> tuple[bool, bool] | None:
        """(first frame of the message from its sender, and another sender had sent it before) for a watched
        message, None for another."""
        senders = self.seen.get(f.msgid)
        if senders is None:
            return None
        me = f.sysid << 8 | f.compid
        if me in senders:
            return (False, False)
        if len(senders) >= min(MAX_FIRST, MAX_SENDERS):
            self.given_up.add("a sender not remembered: its frames are not judged first", record=f.record)
            return (False, False)
        others = bool(senders)
        senders.add(me)
        return (True, others)
