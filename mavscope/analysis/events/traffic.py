"""Event sources about what the systems asked of each other: commands with their ACK, SET_MODE, mission
transfers and operations. Parameter sets and file transfers are in `records.py` (built on the parameter
and object analyses)."""

from __future__ import annotations

from collections.abc import Iterable

from mavscope.analysis.command_log import Command, CommandMatcher, command_json, feed_command
from mavscope.analysis.events.model import COMMAND, MISSION, Event, Fields, addr, at
from mavscope.analysis.mission import TRACKED_MESSAGES, MissionTracker, event_text
from mavscope.analysis.vehicles import Systems
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.semantics import NAN_TEXT, enum_name, float_text

MAV_CMD_DO_SET_MODE, MAV_CMD_COMPONENT_ARM_DISARM = 176, 400
FORCE_ARM_MAGIC = 21196  # param2 of COMPONENT_ARM_DISARM: arm or disarm whatever the checks say


def _short(dialect: Dialect, enum: str, value: int | None, prefix: str) -> str:
    return "none" if value is None else enum_name(dialect, enum, value).removeprefix(prefix)


class Commands:
    """COMMAND_LONG / COMMAND_INT, dated by their first transmission and completed by their ACK (the
    matching of `mavscope commands`), and SET_MODE. A mode asked for is named for the target's autopilot
    and vehicle type."""

    wants = frozenset({"COMMAND_LONG", "COMMAND_INT", "COMMAND_ACK", "SET_MODE"})

    def __init__(self, systems: Systems, dialect: Dialect) -> None:
        self.systems = systems
        self.dialect = dialect
        self.matcher = CommandMatcher(dialect)
        self.modes: dict[int, str] = {}  # id(Command) -> the mode it asks for, named when it was sent

    def _mode(self, target: int, params: tuple[float, float, float]) -> str | None:
        hb = self.systems.vehicle(target)
        autopilot, mav_type = (hb.autopilot, hb.type) if hb is not None else (0, 0)
        return self.systems.modes.command_mode(autopilot, mav_type, params)

    def _event(self, c: Command) -> Event:
        doc = command_json(c, self.dialect)
        name = str(doc["command"]).removeprefix("MAV_CMD_")
        extra = ""
        mode = self.modes.pop(id(c), None)
        if mode is not None:
            doc["mode"] = mode
            extra = f" to {mode}"
        elif c.command == MAV_CMD_COMPONENT_ARM_DISARM:
            p1, p2 = c.params.get("param1"), c.params.get("param2")
            shown = NAN_TEXT if p1 is None else float_text(p1) if isinstance(p1, float) else p1  # (a float32)
            extra = " (arm" if p1 == 1 else " (disarm" if p1 == 0 else f" (param1 {shown}"
            extra += ", forced)" if p2 == FORCE_ARM_MAGIC else ")"
        result = str(doc["result"]).removeprefix("MAV_RESULT_") if c.result is not None else \
            "given up unmatched (more waiting than mavscope follows)" if c.given_up else "no ACK in the capture"
        latency = f" in {c.latency_ms:.1f} ms" if c.latency_ms is not None else ""
        retries = f" after {c.retries} retries" if c.retries else ""
        text = f"{addr(c.sender)} -> {addr(c.target)} {name}{extra}: {result}{latency}{retries}"
        return Event(c.time, c.frames[0], COMMAND, c.sender, text, c.target, doc)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if fields is None:
            return ()
        if f.msgdef is not None and f.msgdef.name == "SET_MODE":
            target = fields.get("target_system")
            base, custom = fields.get("base_mode"), fields.get("custom_mode")
            if not isinstance(target, int) or not isinstance(base, int) or not isinstance(custom, int):
                return ()
            hb = self.systems.vehicle(target)
            autopilot, mav_type = (hb.autopilot, hb.type) if hb is not None else (0, 0)
            mode = self.systems.modes.name(autopilot, mav_type, base, custom)
            return (at(f, COMMAND, f"{addr((f.sysid, f.compid))} -> {target} SET_MODE {mode}", (target, 0),
                       message="SET_MODE", mode=mode, base_mode=base, custom_mode=custom),)
        new, done = feed_command(self.matcher, f, fields)
        if new is not None and new.command == MAV_CMD_DO_SET_MODE:
            p = new.params
            try:
                params = (float(p.get("param1") or 0), float(p.get("param2") or 0), float(p.get("param3") or 0))  # type: ignore[arg-type]
            except (TypeError, ValueError):
                params = None
            asked = self._mode(new.target[0], params) if params is not None else None
            if asked is not None:
                self.modes[id(new)] = asked
        return [self._event(c) for c in done]

    def finish(self) -> Iterable[Event]:
        out = [self._event(c) for c in self.matcher.finish()]
        said = self.matcher.given_up.finding()  # commands given up waiting for their ACK (EventLog says it)
        self.capacity = [said] if said is not None else []
        return out


class Missions:
    """Mission, fence and rally transfers and the other mission operations (MISSION_CLEAR_ALL,
    MISSION_SET_CURRENT...), as `mavscope mission` reconstructs them, each dated by its first frame."""

    wants = TRACKED_MESSAGES  # what the tracker reads: decoded once by the log and handed on

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.tracker = MissionTracker(dialect)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if f.msgdef is not None and f.msgdef.name in TRACKED_MESSAGES:
            self.tracker.feed(f, fields)
        return ()

    def finish(self) -> Iterable[Event]:
        log = self.tracker.finish()
        self.capacity = [log.given_up] if log.given_up is not None else []  # (EventLog: events and audit say it)
        out = []
        for t in log.transfers:
            if not t.frames:
                continue
            mtype = _short(self.dialect, "MAV_MISSION_TYPE", t.mission_type, "MAV_MISSION_TYPE_").lower()
            text = (f"{t.direction} of {t.count} {mtype} items {addr(t.sender)} -> {addr(t.receiver)}: "
                    f"{t.outcome} ({t.reason})")
            out.append(Event(t.start, t.frames[0], MISSION, t.sender, text, t.receiver,
                             {"what": "transfer", "direction": t.direction, "mission_type": mtype, "count": t.count,
                              "items": len(t.items), "outcome": t.outcome, "complete": t.complete}))
        for ev in log.events:
            if not ev.frames:
                continue
            details: dict[str, object] = {"what": ev.kind}
            if ev.kind == "clear-all":
                details["mission_type"] = _short(self.dialect, "MAV_MISSION_TYPE", ev.mission_type,
                                                 "MAV_MISSION_TYPE_").lower()
                details["result"] = None if ev.ack is None else _short(self.dialect, "MAV_MISSION_RESULT",
                                                                       ev.ack.result, "MAV_MISSION_")
            elif ev.kind == "set-current":
                details.update(seq=ev.seq, confirmed=ev.confirmed)
            out.append(Event(ev.time, ev.frames[0], MISSION, ev.sender, event_text(ev, self.dialect), ev.target,
                             details))
        return out
