"""Event sources about what the systems asked of each other: commands with their ACK, SET_MODE, mission
transfers and operations, parameter changes, MAVLink FTP file operations.

`ParamChanges` and `FileTransfers` are deliberately small: they are the places where a fuller parameter
and file-transfer analysis plugs in (an adapter yielding `Event`s from its records replaces them in
`events.log.SOURCES`)."""

from __future__ import annotations

import struct
from collections.abc import Iterable

from mavscope.analysis.command_log import Command, CommandMatcher, command_json
from mavscope.analysis.events.model import COMMAND, FILE, MISSION, PARAM, Addr, Event, Fields, addr, at
from mavscope.analysis.mission import TRACKED_MESSAGES, MissionTracker, event_text
from mavscope.analysis.vehicles import Systems
from mavscope.fields.containers.ftp import ACK, NAK, PATH_OPCODES, ftp, opcode_name
from mavscope.fields.containers.ftp import ERRORS as FTP_ERRORS
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.semantics import enum_name

MAV_CMD_DO_SET_MODE, MAV_CMD_COMPONENT_ARM_DISARM = 176, 400
FORCE_ARM_MAGIC = 21196  # param2 of COMPONENT_ARM_DISARM: arm or disarm whatever the checks say
PENDING_MAX = 4096  # parameter sets and file requests waiting for their answer (the oldest go first)
PARAM_TIMEOUT = 10.0  # s: a PARAM_SET that no PARAM_VALUE confirmed by then is unconfirmed
KNOWN_PARAMS = 65_536  # last values remembered (per system and name), to give a change its old value
_FTP_ERROR = {v: n for v, n in reversed(FTP_ERRORS)}


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
            extra = " (arm" if p1 == 1 else " (disarm" if p1 == 0 else f" (param1 {p1}"
            extra += ", forced)" if p2 == FORCE_ARM_MAGIC else ")"
        result = str(doc["result"]).removeprefix("MAV_RESULT_") if c.result is not None else "no ACK in the capture"
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
        try:
            new, done = self.matcher.add(f, fields)
        except (KeyError, TypeError, ValueError):  # a field that is not a number
            return ()
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
        return [self._event(c) for c in self.matcher.finish()]


class Missions:
    """Mission, fence and rally transfers and the other mission operations (MISSION_CLEAR_ALL,
    MISSION_SET_CURRENT...), as `mavscope mission` reconstructs them, each dated by its first frame."""

    wants: frozenset[str] = frozenset()  # the tracker decodes what it reads

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.tracker = MissionTracker(dialect)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if f.msgdef is not None and f.msgdef.name in TRACKED_MESSAGES:
            self.tracker.feed(f)
        return ()

    def finish(self) -> Iterable[Event]:
        log = self.tracker.finish()
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


def _f32(value: object) -> bytes | None:
    try:
        return struct.pack("<f", value)
    except (struct.error, TypeError, OverflowError):
        return None


class ParamChanges:
    """PARAM_SET, confirmed by the first later PARAM_VALUE from the target system with the same name and the
    same float32 bytes (within PARAM_TIMEOUT); the value before it where a PARAM_VALUE told it. The value is
    shown as the float on the wire (how an autopilot packs integer types into it is the parameter
    analysis's business)."""

    wants = frozenset({"PARAM_SET", "PARAM_VALUE"})

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        # (target, name) -> (the PARAM_SET, its value, its float32 bytes, the value before it, the value reported since)
        self.pending: dict[tuple[int, str], tuple[Frame, float, bytes, object, object]] = {}
        self.known: dict[tuple[int, str], object] = {}

    def _event(self, f: Frame, target: int, name: str, value: float, previous: object, confirmed: bool,
               latency_ms: float | None, reported: object = None) -> Event:
        was = f" (was {previous:g})" if isinstance(previous, float) else ""
        if confirmed:
            how = "confirmed" + (f" in {latency_ms:.1f} ms" if latency_ms is not None else "")
        elif reported is not None:
            how = f"not confirmed: {target} reports {reported:g}" if isinstance(reported, float) else "not confirmed"
        else:
            how = "not confirmed: no PARAM_VALUE with that value"
        return at(f, PARAM, f"{addr((f.sysid, f.compid))} sets {target} {name} = {value:g}{was}: {how}", (target, 0),
                  name=name, value=value, previous=previous, confirmed=confirmed, latency_ms=latency_ms)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if fields is None:
            return ()
        name, value = fields.get("param_id"), fields.get("param_value")
        if not isinstance(name, str) or not isinstance(value, float):
            return ()
        out: list[Event] = []
        if f.msgdef is not None and f.msgdef.name == "PARAM_SET":
            target = fields.get("target_system")
            raw = _f32(value)
            if not isinstance(target, int) or raw is None:
                return ()
            key = (target, name)
            if key not in self.pending:
                self.pending[key] = (f, value, raw, self.known.get(key), None)
                if len(self.pending) > PENDING_MAX:
                    old = next(iter(self.pending))
                    out.extend(self._expire(old))
            return out
        key = (f.sysid, name)
        entry = self.pending.get(key)
        if entry is not None:
            sent, set_value, raw, before, _ = entry
            if _f32(value) == raw:
                del self.pending[key]
                latency = (f.time - sent.time) * 1000 if f.time is not None and sent.time is not None else None
                out.append(self._event(sent, key[0], name, set_value, before, True, latency))
            else:
                self.pending[key] = (sent, set_value, raw, before, value)
        if key in self.known or len(self.known) < KNOWN_PARAMS:
            self.known[key] = value
        while self.pending and f.time is not None:  # give up on sets no confirmation followed in time (oldest first)
            k, (sent, *_) = next(iter(self.pending.items()))
            if sent.time is None or f.time - sent.time <= PARAM_TIMEOUT:
                break
            out.extend(self._expire(k))
        return out

    def _expire(self, key: tuple[int, str]) -> list[Event]:
        sent, value, _, before, reported = self.pending.pop(key)
        return [self._event(sent, key[0], key[1], value, before, False, None, reported)]

    def finish(self) -> Iterable[Event]:
        out: list[Event] = []
        for key in list(self.pending):
            out.extend(self._expire(key))
        return out


class FileTransfers:
    """MAVLink FTP requests that name a file or directory (OpenFileRO/WO, CreateFile, RemoveFile, ListDirectory,
    Rename...), each with the ACK or NAK that answered it (session and size of an open, the error of a NAK)."""

    wants = frozenset({"FILE_TRANSFER_PROTOCOL"})

    def __init__(self) -> None:
        self.pending: dict[tuple[Addr, int], tuple[Frame, int, str, int]] = {}  # (requester, server) -> request

    def _event(self, f: Frame, server: int, opcode: int, path: str, answer: str, **details: object) -> Event:
        op = opcode_name(opcode)
        return at(f, FILE, f"{addr((f.sysid, f.compid))} -> {server} {op} {path}: {answer}", (server, 0),
                  opcode=op, path=path, answer=answer, **details)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        if fields is None:
            return ()
        p = ftp(f)
        target, tcomp = fields.get("target_system"), fields.get("target_component")
        if p is None or not isinstance(target, int) or not isinstance(tcomp, int):
            return ()
        out: list[Event] = []
        if p.opcode in PATH_OPCODES and p.path is not None:
            key = ((f.sysid, f.compid), target)
            prev = self.pending.get(key)
            if prev is not None and prev[1] == p.opcode and prev[2] == p.path:
                return ()  # the same request again (a retry)
            if prev is not None:
                out.append(self._event(prev[0], target, prev[1], prev[2], "no answer"))
            self.pending[key] = (f, p.opcode, p.path, p.seq)
            if len(self.pending) > PENDING_MAX:
                (req, server), (rf, op, path, _) = next(iter(self.pending.items()))
                del self.pending[(req, server)]
                out.append(self._event(rf, server, op, path, "no answer"))
            return out
        if p.opcode not in (ACK, NAK):
            return ()
        entry = self.pending.get(((target, tcomp), f.sysid))  # the server answers the requester's sysid/compid
        if entry is None or entry[1] != p.req_opcode:
            return ()
        req_frame, opcode, path, _ = entry
        del self.pending[((req_frame.sysid, req_frame.compid), f.sysid)]
        if p.opcode == ACK:
            details: dict[str, object] = {"session": p.session, "answer_frame": f.record}
            answer = "ACK"
            if p.file_size is not None:
                details["size"] = p.file_size
                answer += f" (session {p.session}, size {p.file_size})"
            return (self._event(req_frame, f.sysid, opcode, path, answer, **details),)
        err = _FTP_ERROR.get(p.error, str(p.error)) if p.error is not None else "?"
        return (self._event(req_frame, f.sysid, opcode, path, f"NAK {err}", error=err, errno=p.errno,
                            answer_frame=f.record),)

    def finish(self) -> Iterable[Event]:
        out = [self._event(rf, server, op, path, "no answer")
               for (_, server), (rf, op, path, _) in self.pending.items()]
        self.pending.clear()
        return out
