"""Event sources about the vehicles themselves: state from HEARTBEAT (arming, flight mode, failsafe
states), reboots, mission progress (MISSION_CURRENT, MISSION_ITEM_REACHED) and STATUSTEXT."""

from __future__ import annotations

import re
from collections.abc import Iterable

from mavscope.analysis.events.model import (
    ARMING,
    FAILSAFE,
    MISSION,
    MODE,
    REBOOT,
    STATUSTEXT,
    VEHICLE,
    Addr,
    Event,
    Fields,
    addr,
    at,
)
from mavscope.analysis.events.statustext import StatusText, StatusTextJoiner
from mavscope.analysis.vehicles import FAILSAFE_STATES, MAX_SENDERS, Heartbeat, Systems, heartbeat
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.semantics import enum_name

REBOOT_BACK_MS = 1000  # the boot clock stepping back this far or more is a reboot
# messages whose time_boot_ms is the sender's boot clock, streamed by ArduPilot and PX4 alike: PX4 in 2017
# sent no SYSTEM_TIME, and came back from its reboot with RC_CHANNELS (px4_2018_params_offboard.tlog)
BOOT_CLOCKS = frozenset({"SYSTEM_TIME", "ATTITUDE", "GLOBAL_POSITION_INT", "RC_CHANNELS"})
FAILSAFE_TEXT = re.compile(r"fail[ -]?safe", re.IGNORECASE)


def _short(name: str, prefix: str) -> str:
    return name.removeprefix(prefix)


class VehicleStates:
    """From each vehicle's HEARTBEATs: its first appearance and type changes (`vehicle`), arming and
    disarming (`arming`), flight mode changes (`mode`, named per autopilot and vehicle type), entering
    and leaving MAV_STATE_CRITICAL / EMERGENCY / FLIGHT_TERMINATION (`failsafe`); from BOOT_CLOCKS, a boot
    clock that steps back (`reboot`)."""

    wants = frozenset({"HEARTBEAT"}) | BOOT_CLOCKS

    def __init__(self, systems: Systems, dialect: Dialect) -> None:
        self.systems = systems
        self.dialect = dialect
        self.prev: dict[Addr, Heartbeat] = {}
        self.boot: dict[Addr, int] = {}

    def _state(self, value: int) -> str:
        return _short(enum_name(self.dialect, "MAV_STATE", value), "MAV_STATE_")

    def _type(self, value: int) -> str:
        return _short(enum_name(self.dialect, "MAV_TYPE", value), "MAV_TYPE_")

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if fields is None:
            return ()
        me = (f.sysid, f.compid)
        if f.msgid != 0:
            return self._boot_clock(f, me, fields)
        hb = heartbeat(fields)
        if hb is None or not self.systems.modes.is_vehicle(hb.type, hb.autopilot):
            return ()
        prev = self.prev.get(me)
        if prev is None and len(self.prev) >= MAX_SENDERS:
            return ()
        self.prev[me] = hb
        mode = self.systems.mode_name(hb)
        autopilot = _short(enum_name(self.dialect, "MAV_AUTOPILOT", hb.autopilot), "MAV_AUTOPILOT_")
        out: list[Event] = []
        if prev is None:
            state = "armed" if hb.armed else "disarmed"
            out.append(at(f, VEHICLE, f"{addr(me)} is a {self._type(hb.type)} ({autopilot}): {mode}, {state}, "
                                      f"{self._state(hb.system_status)}", type=self._type(hb.type),
                          autopilot=autopilot, mode=mode, armed=hb.armed, state=self._state(hb.system_status)))
            if hb.system_status in FAILSAFE_STATES:
                out.append(at(f, FAILSAFE, f"{addr(me)} reports {self._state(hb.system_status)}",
                              state=self._state(hb.system_status), active=True, source="HEARTBEAT"))
            return out
        if hb.type != prev.type:
            out.append(at(f, VEHICLE, f"{addr(me)} now reports type {self._type(hb.type)} (was "
                                      f"{self._type(prev.type)})", type=self._type(hb.type),
                          autopilot=autopilot, mode=mode, armed=hb.armed, state=self._state(hb.system_status)))
        if hb.armed != prev.armed:
            out.append(at(f, ARMING, f"{addr(me)} {'armed' if hb.armed else 'disarmed'} in {mode}",
                          armed=hb.armed, mode=mode))
        before = self.systems.mode_name(prev)
        if mode != before:
            out.append(at(f, MODE, f"{addr(me)} mode {before} -> {mode}", mode=mode, previous=before,
                          custom_mode=hb.custom_mode, base_mode=hb.base_mode))
        was, now = prev.system_status in FAILSAFE_STATES, hb.system_status in FAILSAFE_STATES
        if now and hb.system_status != prev.system_status:
            out.append(at(f, FAILSAFE, f"{addr(me)} reports {self._state(hb.system_status)} (was "
                                       f"{self._state(prev.system_status)})", state=self._state(hb.system_status),
                          active=True, source="HEARTBEAT"))
        elif was and not now:
            out.append(at(f, FAILSAFE, f"{addr(me)} leaves {self._state(prev.system_status)} for "
                                       f"{self._state(hb.system_status)}", state=self._state(hb.system_status),
                          active=False, source="HEARTBEAT"))
        return out

    def _boot_clock(self, f: Frame, me: Addr, fields: Fields) -> Iterable[Event]:
        boot = fields.get("time_boot_ms")
        if not isinstance(boot, int) or boot == 0:  # ground stations send 0
            return ()
        last = self.boot.get(me)
        if last is None and len(self.boot) >= MAX_SENDERS:
            return ()
        self.boot[me] = boot
        if last is not None and boot + REBOOT_BACK_MS <= last:
            return (at(f, REBOOT, f"{addr(me)} rebooted: its boot clock went from {last / 1000:.3f} s to "
                                  f"{boot / 1000:.3f} s", before_ms=last, after_ms=boot),)
        return ()

    def finish(self) -> Iterable[Event]:
        return ()


class MissionProgress:
    """The mission item each vehicle is on (MISSION_CURRENT, when it changes) and the items it reached
    (MISSION_ITEM_REACHED; a repeat of the same item directly after is not a new event)."""

    wants = frozenset({"MISSION_CURRENT", "MISSION_ITEM_REACHED"})

    def __init__(self) -> None:
        self.current: dict[Addr, int] = {}
        self.reached: dict[Addr, int] = {}

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if fields is None:
            return ()
        me = (f.sysid, f.compid)
        seq = fields.get("seq")
        if not isinstance(seq, int):
            return ()
        table = self.current if f.msgdef is not None and f.msgdef.name == "MISSION_CURRENT" else self.reached
        last = table.get(me)
        if last == seq or (last is None and len(table) >= MAX_SENDERS):
            return ()
        table[me] = seq
        if table is self.reached:
            return (at(f, MISSION, f"{addr(me)} reached mission item {seq}", what="reached", seq=seq),)
        if last is None:  # the first report is where the vehicle is, not a change
            return ()
        total = fields.get("total")
        of = f" of {total}" if isinstance(total, int) and total not in (0, 0xFFFF) else ""
        return (at(f, MISSION, f"{addr(me)} current mission item {last} -> {seq}{of}", what="current", seq=seq,
                   previous=last),)

    def finish(self) -> Iterable[Event]:
        return ()


class StatusTexts:
    """STATUSTEXT with its severity, as a ground station shows them: the chunks of a long text joined into
    one event, dated by the first, as QGroundControl joins them, missing chunks said (statustext.py). A
    text that mentions a failsafe is a `failsafe` event."""

    wants = frozenset({"STATUSTEXT"})

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.joiner = StatusTextJoiner()

    def _event(self, t: StatusText) -> Event:
        sev = _short(enum_name(self.dialect, "MAV_SEVERITY", t.severity), "MAV_SEVERITY_")
        text = t.text
        kind = FAILSAFE if FAILSAFE_TEXT.search(text) else STATUSTEXT
        details: dict[str, object] = {"severity": sev, "severity_id": t.severity, "message": text}
        if t.ident:
            details.update({"id": t.ident, "chunks": len(t.frames), "complete": t.complete, "end": t.end.value})
            if len(t.frames) > 1:
                details["frames"] = list(t.frames)
            if t.missing:
                details["missing"] = list(t.missing)
        if kind == FAILSAFE:
            details["source"] = "STATUSTEXT"
        return Event(t.time, t.frame, kind, t.sender, f"{addr(t.sender)} {sev}: {text}", None, details)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if fields is None:
            return ()
        return [self._event(t) for t in self.joiner.add(f, fields)]

    def finish(self) -> Iterable[Event]:
        return [self._event(t) for t in self.joiner.finish()]
