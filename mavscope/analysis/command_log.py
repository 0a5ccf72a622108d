"""The command log: every COMMAND_LONG / COMMAND_INT with the COMMAND_ACK that answered it.

A command is matched to the first final ACK (any result but MAV_RESULT_IN_PROGRESS) that comes from
the system it targeted (any component when it targeted component 0), for the same command id, and,
where the ACK says (MAVLink 2 extensions), addressed to the sender. The same command from the same
sender to the same target before that ACK is a retry (COMMAND_LONG counts them in `confirmation`), not
a new command. `latency_ms` runs from the first transmission to the ACK. Commands without an ACK are
unanswered; ACKs that match no command are listed apart.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.mavlink.semantics import (
    COMMAND_PARAM_INDEX,
    INT_COORDINATE_MESSAGES,
    command_param_name,
    enum_name,
    finite,
    int_coordinate,
)

MAV_RESULT_IN_PROGRESS = 5
COMMAND_MESSAGES = frozenset({"COMMAND_LONG", "COMMAND_INT", "COMMAND_ACK"})
PENDING_MAX = 4096  # commands waiting for their ACK (the oldest is given up first)
ORPHANS_KEPT = 10_000  # ACKs matching no command, listed (all are counted)


@dataclass
class Command:
    message: str  # COMMAND_LONG or COMMAND_INT
    command: int
    sender: tuple[int, int]
    target: tuple[int, int]
    params: dict[str, object]
    time: float | None
    frames: list[int] = field(default_factory=list)
    retries: int = 0
    result: int | None = None
    progress: list[int] = field(default_factory=list)
    ack_frame: int | None = None
    ack_time: float | None = None
    src: str | None = None

    @property
    def latency_ms(self) -> float | None:
        if self.ack_time is None or self.time is None:
            return None
        return round((self.ack_time - self.time) * 1000, 3)


def _name(dialect: Dialect, enum: str, value: int | None) -> str | None:
    return None if value is None else enum_name(dialect, enum, value)


class CommandMatcher:
    """Commands and their ACKs in one pass: `add(frame, fields)` per COMMAND_LONG / COMMAND_INT /
    COMMAND_ACK frame (decoded `fields`) in capture order returns the commands that frame completed (an
    ACK answers at most one); `finish()` the ones still unanswered. At most PENDING_MAX commands wait for
    their ACK (the oldest is given up as unanswered), so the state is bounded whatever the capture."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.pending: list[Command] = []
        self.orphans: list[dict[str, object]] = []  # ACKs that answer no command (the first ORPHANS_KEPT)
        self.orphan_count = 0

    def add(self, f: Frame, fields: dict[str, object]) -> tuple[Command | None, list[Command]]:
        """(the new command this frame sent, or None; the commands it completed or pushed out unanswered)."""
        name = f.msgdef.name if f.msgdef is not None else ""
        me = (f.sysid, f.compid)
        if name != "COMMAND_ACK":
            cmd_id = int(fields["command"])  # type: ignore[call-overload]
            target = (int(fields["target_system"]), int(fields["target_component"]))  # type: ignore[call-overload]
            same = next((c for c in self.pending if c.message == name and c.command == cmd_id and c.sender == me
                         and c.target == target), None)
            if same is not None:
                same.retries += 1
                same.frames.append(f.record)
                return None, []
            names = [n for n in ("param1", "param2", "param3", "param4", "param5", "param6", "param7", "x", "y", "z",
                                 "frame", "confirmation") if n in fields]
            params: dict[str, object] = {n: finite(fields[n]) for n in names}
            if name in INT_COORDINATE_MESSAGES:  # degrees in a global frame, metres in a local one
                frame = params.get("frame")
                params["x"] = int_coordinate(int(params["x"]), frame)  # type: ignore[call-overload, arg-type]
                params["y"] = int_coordinate(int(params["y"]), frame)  # type: ignore[call-overload, arg-type]
            src = None if f.src is None else f.src.text
            c = Command(name, cmd_id, me, target, params, f.time, [f.record], src=src)
            self.pending.append(c)
            dropped = [self.pending.pop(0)] if len(self.pending) > PENDING_MAX else []
            return c, dropped
        cmd_id = int(fields["command"])  # type: ignore[call-overload]
        result = int(fields["result"])  # type: ignore[call-overload]
        to_sys, to_comp = fields.get("target_system", 0), fields.get("target_component", 0)
        match = None
        for c in self.pending:
            if c.command != cmd_id or c.target[0] not in (0, f.sysid) or c.target[1] not in (0, f.compid):
                continue
            if to_sys and to_sys != c.sender[0]:
                continue
            if to_comp and to_comp != c.sender[1]:
                continue
            match = c
            break
        if match is None:
            self.orphan_count += 1
            if len(self.orphans) < ORPHANS_KEPT:
                self.orphans.append({"frame": f.record, "command": _name(self.dialect, "MAV_CMD", cmd_id),
                                     "result": _name(self.dialect, "MAV_RESULT", result), "from": [f.sysid, f.compid],
                                     "time": f.time})
            return None, []
        if result == MAV_RESULT_IN_PROGRESS:
            match.progress.append(int(fields.get("progress", 0) or 0))  # type: ignore[call-overload]
            match.frames.append(f.record)
            return None, []
        match.result, match.ack_frame, match.ack_time = result, f.record, f.time
        self.pending.remove(match)
        return None, [match]

    def finish(self) -> list[Command]:
        """The commands no ACK answered."""
        out, self.pending = self.pending, []
        return out


def reconstruct(frames: Iterable[Frame], dialect: Dialect) -> tuple[list[Command], list[dict[str, object]]]:
    """(commands in the order first sent, ACKs that answer no command)."""
    commands: list[Command] = []
    matcher = CommandMatcher(dialect)
    for f in frames:
        md = f.msgdef
        if md is None or md.name not in COMMAND_MESSAGES or f.crc_status is CrcStatus.BAD:
            continue
        fields = decode_payload(f)
        if fields is None:
            continue
        new, _ = matcher.add(f, fields)
        if new is not None:
            commands.append(new)
    return commands, matcher.orphans


def _param_names(c: Command, dialect: Dialect) -> dict[str, str]:
    """The names of the parameter values the XML names (an enum entry, a message id's message)."""
    out = {}
    for key, index in COMMAND_PARAM_INDEX.items():
        if key in c.params and not (c.message == "COMMAND_INT" and key.startswith("param") and index > 4):
            name = command_param_name(dialect, c.command, index, c.params[key])
            if name is not None:
                out[key] = name
    return out


def command_json(c: Command, dialect: Dialect) -> dict[str, object]:
    labels = {f"param{i}": label for i, label, _ in dialect.command_params(c.command)}
    if c.message == "COMMAND_INT":
        labels |= {{"param5": "x", "param6": "y", "param7": "z"}.get(k, k): v for k, v in labels.items()
                   if k in ("param5", "param6", "param7")}
    return {
        "command": _name(dialect, "MAV_CMD", c.command), "command_id": c.command, "message": c.message,
        "from": list(c.sender), "to": list(c.target), "src": c.src, "time": c.time,
        "result": _name(dialect, "MAV_RESULT", c.result), "result_id": c.result,
        "answered": c.result is not None, "latency_ms": c.latency_ms, "retries": c.retries,
        "progress": c.progress, "params": c.params,
        "param_labels": {k: v for k, v in labels.items() if k in c.params},
        "param_names": _param_names(c, dialect),
        "frames": c.frames, "ack_frame": c.ack_frame,
    }
