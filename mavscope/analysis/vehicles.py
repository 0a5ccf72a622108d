"""Who is who on the link: what each sender's last HEARTBEAT says (type, autopilot, modes, state).

`Systems.see(frame, fields)` takes every HEARTBEAT (decoded `fields`); the analyses ask which system is
a vehicle, whether it is armed, what its flight mode is called and which systems are ground stations.
Bounded: at most MAX_SENDERS senders, which is every (system id, component id) pair, so a table keyed by
sender never fills: a flood of made-up ids cannot push a vehicle out of it, nothing is given up (the other
analyses' sender tables take the same bound: control, gnss, events; docs/security.md, "Bounds").
"""

from __future__ import annotations

from dataclasses import dataclass

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Addr, Frame
from mavscope.mavlink.modes import armed, modes_for

MAX_SENDERS = 1 << 16  # 256 system ids x 256 component ids (a sender costs Systems about 400 bytes)
MAV_STATE_CRITICAL, MAV_STATE_EMERGENCY, MAV_STATE_FLIGHT_TERMINATION = 5, 6, 8
FAILSAFE_STATES = frozenset({MAV_STATE_CRITICAL, MAV_STATE_EMERGENCY, MAV_STATE_FLIGHT_TERMINATION})



@dataclass(frozen=True, slots=True)
class Heartbeat:
    """What one HEARTBEAT says."""

    type: int
    autopilot: int
    base_mode: int
    custom_mode: int
    system_status: int

    @property
    def armed(self) -> bool:
        return armed(self.base_mode)


def heartbeat(fields: dict[str, object]) -> Heartbeat | None:
    """The HEARTBEAT of decoded fields (None when a field is missing or not a number)."""
    try:
        return Heartbeat(int(fields["type"]), int(fields["autopilot"]), int(fields["base_mode"]),  # type: ignore[call-overload]
                         int(fields["custom_mode"]), int(fields["system_status"]))  # type: ignore[call-overload]
    except (KeyError, TypeError, ValueError):
        return None


class Systems:
    """The last HEARTBEAT of each sender, and what follows from it."""

    def __init__(self, dialect: Dialect) -> None:
        self.modes = modes_for(dialect)
        self.last: dict[Addr, Heartbeat] = {}
        self.gcs: set[int] = set()
        self.vehicles: dict[int, Addr] = {}  # sysid -> the component whose HEARTBEAT is the vehicle's

    def see(self, f: Frame, fields: dict[str, object]) -> Heartbeat | None:
        """Record a HEARTBEAT frame; returns what it says."""
        hb = heartbeat(fields)
        if hb is None:
            return None
        addr = (f.sysid, f.compid)
        if addr not in self.last and len(self.last) >= MAX_SENDERS:
            return hb
        self.last[addr] = hb
        if hb.type in self.modes.gcs:
            self.gcs.add(f.sysid)
        elif self.modes.is_vehicle(hb.type, hb.autopilot):
            known = self.vehicles.get(f.sysid)
            if known is None or (known[1] != 1 and f.compid == 1):  # the autopilot is component 1
                self.vehicles[f.sysid] = addr
        return hb

    def is_vehicle(self, addr: Addr) -> bool:
        hb = self.last.get(addr)
        return hb is not None and self.modes.is_vehicle(hb.type, hb.autopilot)

    def vehicle(self, sysid: int) -> Heartbeat | None:
        """The vehicle HEARTBEAT of system `sysid` (its autopilot's), None when it sent none."""
        addr = self.vehicles.get(sysid)
        return None if addr is None else self.last.get(addr)

    def mode_name(self, hb: Heartbeat) -> str:
        return self.modes.name(hb.autopilot, hb.type, hb.base_mode, hb.custom_mode)

    def aerial(self, sysid: int) -> bool:
        hb = self.vehicle(sysid)
        return hb is not None and hb.type in self.modes.aerial
