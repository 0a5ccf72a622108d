"""The command log: every COMMAND_LONG / COMMAND_INT with the COMMAND_ACK that answered it.

A command is matched to the first final ACK (any result but MAV_RESULT_IN_PROGRESS) that comes from
the system it targeted (any component when it targeted component 0), for the same command id, and,
where the ACK says (MAVLink 2 extensions), addressed to the sender. The same command from the same
sender to the same target before that ACK is a retry (COMMAND_LONG counts them in `confirmation`), not
a new command. `latency_ms` runs from the first transmission to the ACK. Commands without an ACK are
unanswered; ACKs that match no command are listed apart.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable
from dataclasses import dataclass, field

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.floats import shortest_fields
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.mavlink.semantics import (
    COMMAND_PARAM_INDEX,
    INT_COORDINATE_MESSAGES,
    command_param_name,
    enum_name,
    finite,
    int_coordinate,
)
from mavscope.notes import GivenUp

MAV_RESULT_IN_PROGRESS = 5
COMMAND_MESSAGES = frozenset({"COMMAND_LONG", "COMMAND_INT", "COMMAND_ACK"})
PENDING_MAX = 4096  # commands waiting for their ACK (past it the newest but the one just sent is given up: said)
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
    given_up: bool = False  # waited past PENDING_MAX: mavscope stopped matching it (an ACK may have come)

    @property
    def latency_ms(self) -> float | None:
        if self.ack_time is None or self.time is None:
            return None
        return round((self.ack_time - self.time) * 1000, 3)


def _name(dialect: Dialect, enum: str, value: int | None) -> str | None:
    return None if value is None else enum_name(dialect, enum, value)


Key = tuple[str, int, tuple[int, int], tuple[int, int]]  # (message, command id, sender, target)


class CommandMatcher:
    """Commands and their ACKs in one pass: `add(frame, fields)` per COMMAND_LONG / COMMAND_INT /
    COMMAND_ACK frame (decoded `fields`) in capture order returns the commands that frame completed (an
    ACK answers at most one); `finish()` the ones still unanswered. At most PENDING_MAX commands wait for
    their ACK, so the state is bounded whatever the capture: past that, the command sent last before the new
    one is given up as unanswered (`given_up` counts them, as `capacity`): a flood of commands from made-up
    senders gives up its own, never the commands that were waiting before it (oldest first, an ARM sent
    before a flood would be called unanswered and its ACK an orphan).

    A frame costs the same however many commands wait: a retry is found by its key (message, command,
    sender, target), and an ACK's candidates, oldest first, under the command and the target it can answer
    (the sending system or 0, the sending component or 0), narrowed to the sender the ACK names, if any."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self._pending: OrderedDict[Key, Command] = OrderedDict()  # in the order first sent
        self._order: dict[Key, int] = {}  # key -> its place in that order (the oldest candidate wins)
        self._sent = 0
        # (command id, target system, target component[, sender system or -1[, sender component]]) -> those
        # waiting: the groups an ACK looks in, by what it says of the sender
        self._by: dict[tuple[int, ...], OrderedDict[Key, Command]] = {}
        self.orphans: list[dict[str, object]] = []  # ACKs that answer no command (the first ORPHANS_KEPT)
        self.orphan_count = 0
        self.given_up = GivenUp(f"commands waiting for their ACK (at most {PENDING_MAX:,})", "commands")

    @staticmethod
    def _groups(key: Key) -> tuple[tuple[int, ...], ...]:
        _, cmd_id, (ssys, scomp), (tsys, tcomp) = key
        return ((cmd_id, tsys, tcomp), (cmd_id, tsys, tcomp, ssys), (cmd_id, tsys, tcomp, ssys, scomp),
                (cmd_id, tsys, tcomp, -1, scomp))

    def _wait(self, key: Key, c: Command) -> None:
        self._pending[key] = c
        self._order[key] = self._sent
        self._sent += 1
        for g in self._groups(key):
            self._by.setdefault(g, OrderedDict())[key] = c

    def _done(self, key: Key) -> Command:
        c = self._pending.pop(key)
        del self._order[key]
        for g in self._groups(key):
            group = self._by[g]
            del group[key]
            if not group:
                del self._by[g]
        return c

    def _answered(self, cmd_id: int, sysid: int, compid: int, to_sys: int, to_comp: int) -> Key | None:
        """The oldest waiting command an ACK of `cmd_id` from sysid/compid, addressed to to_sys/to_comp
        (0: not said), answers."""
        best: Key | None = None
        sender = (to_sys or -1, to_comp) if to_comp else (to_sys,) if to_sys else ()
        for tsys in {0, sysid}:
            for tcomp in {0, compid}:
                group = self._by.get((cmd_id, tsys, tcomp, *sender))
                if group is None:
                    continue
                key = next(iter(group))
                if best is None or self._order[key] < self._order[best]:
                    best = key
        return best

    def add(self, f: Frame, fields: dict[str, object]) -> tuple[Command | None, list[Command]]:
        """(the new command this frame sent, or None; the commands it completed or pushed out unanswered)."""
        name = f.msgdef.name if f.msgdef is not None else ""
        me = (f.sysid, f.compid)
        if name != "COMMAND_ACK":
            cmd_id = int(fields["command"])  # type: ignore[call-overload]
            target = (int(fields["target_system"]), int(fields["target_component"]))  # type: ignore[call-overload]
            key: Key = (name, cmd_id, me, target)
            same = self._pending.get(key)
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
            self._wait(key, c)
            dropped: list[Command] = []
            if len(self._pending) > PENDING_MAX:
                newest = reversed(self._pending)  # (the house policy, notes.pop_newest's, over the groups too)
                gone = next(newest)
                gone = next(newest) if gone == key else gone
                dropped.append(self._done(gone))
                dropped[0].given_up = True
                self.given_up.add(f"gave up {gone[0]} {gone[1]} from {gone[2][0]}/{gone[2][1]} (frame "
                                  f"{dropped[0].frames[0]}) as unanswered", record=f.record)
            return c, dropped
        cmd_id = int(fields["command"])  # type: ignore[call-overload]
        result = int(fields["result"])  # type: ignore[call-overload]
        to_sys = int(fields.get("target_system", 0) or 0)  # type: ignore[call-overload]
        to_comp = int(fields.get("target_component", 0) or 0)  # type: ignore[call-overload]
        found = self._answered(cmd_id, f.sysid, f.compid, to_sys, to_comp)
        if found is None:
            self.orphan_count += 1
            if len(self.orphans) < ORPHANS_KEPT:
                self.orphans.append({"frame": f.record, "command": _name(self.dialect, "MAV_CMD", cmd_id),
                                     "result": _name(self.dialect, "MAV_RESULT", result), "from": [f.sysid, f.compid],
                                     "time": f.time})
            return None, []
        match = self._pending[found]
        if result == MAV_RESULT_IN_PROGRESS:
            match.progress.append(int(fields.get("progress", 0) or 0))  # type: ignore[call-overload]
            match.frames.append(f.record)
            return None, []
        match.result, match.ack_frame, match.ack_time = result, f.record, f.time
        self._done(found)
        return None, [match]

    def finish(self) -> list[Command]:
        """The commands no ACK answered."""
        out = list(self._pending.values())
        self._pending.clear()
        self._order.clear()
        self._by.clear()
        return out


def takes(f: Frame) -> bool:
    """Whether the matcher takes frame `f`: a command or ACK whose CRC is not bad."""
    md = f.msgdef
    return md is not None and md.name in COMMAND_MESSAGES and f.crc_status is not CrcStatus.BAD


def command_fields(f: Frame) -> dict[str, object] | None:
    """The decoded fields of a command or ACK frame the matcher takes (None for any other frame)."""
    return decode_payload(f) if takes(f) else None


def feed_command(matcher: CommandMatcher, f: Frame,
                 fields: dict[str, object] | None = None) -> tuple[Command | None, list[Command]]:
    """The one way a frame reaches a CommandMatcher (`commands`, `events`, `audit`, the export): what
    `matcher.add` returns, or nothing for a frame it does not take (`takes`) and for a command whose fields
    are not numbers (a hostile dialect's COMMAND_LONG: it names no command to follow). `fields`: the frame's
    decoded payload where the caller has decoded it already (decoded once), else decoded here."""
    if not takes(f):
        return None, []
    if fields is None:
        fields = decode_payload(f)
        if fields is None:
            return None, []
    try:
        return matcher.add(f, fields)
    except (KeyError, TypeError, ValueError, OverflowError):
        return None, []


def reconstruct(frames: Iterable[Frame], dialect: Dialect) -> tuple[list[Command], list[dict[str, object]], GivenUp]:
    """(commands in the order first sent, ACKs that answer no command, what the matcher gave up)."""
    commands: list[Command] = []
    matcher = CommandMatcher(dialect)
    for f in frames:
        new, _ = feed_command(matcher, f)
        if new is not None:
            commands.append(new)
    return commands, matcher.orphans, matcher.given_up


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
        "answered": c.result is not None, "given_up": c.given_up, "latency_ms": c.latency_ms, "retries": c.retries,
        # a float32 parameter (param1..7, COMMAND_INT's z) as the shortest decimal that reads back as it (30.48);
        # the matching and the names above use the values themselves
        "progress": c.progress, "params": shortest_fields(dialect.by_name.get(c.message), c.params),
        "param_labels": {k: v for k, v in labels.items() if k in c.params},
        "param_names": _param_names(c, dialect),
        "frames": c.frames, "ack_frame": c.ack_frame,
    }
