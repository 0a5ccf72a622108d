"""Who commands each vehicle (the expert's CommandSources detector), and the words of its findings.

A vehicle's first commander is the first sender of a commanding message to it. Every other system id
that commands it afterwards is a new commander: one `new-commander` finding per vehicle names them (the
first COMMANDERS_SHOWN with the message they sent, all counted, the first frame of each listed). A capture
that sprays commands from every one of the 65,536 senders at every vehicle thus gives at most one finding
per vehicle, and the detector's memory stays a bitmap of senders per vehicle (8 KB), whatever the
capture's length.
"""

from __future__ import annotations

from mavscope.analysis.framelist import frame_numbers
from mavscope.endpoint import Endpoint
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding, finding

# Messages that tell a vehicle what to do (their target_system is the vehicle commanded).
COMMANDING = frozenset({
    "COMMAND_LONG", "COMMAND_INT", "SET_MODE", "MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_SET_CURRENT",
    "MISSION_ITEM", "MISSION_ITEM_INT", "PARAM_SET", "PARAM_EXT_SET", "SET_POSITION_TARGET_LOCAL_NED",
    "SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET", "MANUAL_CONTROL", "RC_CHANNELS_OVERRIDE",
    "SETUP_SIGNING", "SET_HOME_POSITION", "SET_GPS_GLOBAL_ORIGIN", "FILE_TRANSFER_PROTOCOL",
})
MAV_TYPE_GCS = 6
COMMANDERS_SHOWN = 3  # new commanders of a vehicle named in its finding (all are counted)

Link = tuple[int, int]
Fields = dict[str, object]


def target_of(fields: Fields) -> object:
    """The system a commanding message addresses: `target_system`, or MANUAL_CONTROL's `target`."""
    return fields.get("target_system", fields.get("target"))


class Commanded:
    """The new commanders of one vehicle: the senders (a bitmap of sysid << 8 | compid), the first
    COMMANDERS_SHOWN of them with the message each first sent, the first frame of each (`frames.count`:
    how many there are)."""

    __slots__ = ("first", "senders", "shown", "frames")

    def __init__(self, first: Link) -> None:
        self.first = first  # the vehicle's first commander
        self.senders = bytearray(8192)
        self.shown: list[tuple[Link, str]] = []
        self.frames = frame_numbers()

    def add(self, sender: Link, name: str, record: int) -> None:
        """Sender `sender` commands the vehicle (with `name`, in frame `record`): counted the first time."""
        bit = sender[0] << 8 | sender[1]
        if self.senders[bit >> 3] >> (bit & 7) & 1:
            return
        self.senders[bit >> 3] |= 1 << (bit & 7)
        if len(self.shown) < COMMANDERS_SHOWN:
            self.shown.append((sender, name))
        self.frames.add(record)


class CommandSources:
    """Who commands each vehicle: other system ids commanding it after the first, the same id
    commanding from another network endpoint, commands from a system that never sent a HEARTBEAT.
    Commands to a ground station (HEARTBEAT type GCS) are not about a vehicle: they are set aside until
    the end, when every HEARTBEAT has been seen."""

    clean: frozenset[str | int] = COMMANDING | {0}  # message id 0: the HEARTBEATs, by id as `add` tells them
    notes: frozenset[str] = frozenset()  # it reads its messages alone, whatever their notes

    def __init__(self) -> None:
        self.gcs: set[int] = set()
        self.heartbeat_seen: set[Link] = set()
        self.first_commander: dict[int, Link] = {}
        self.commanded: dict[int, Commanded] = {}  # target system -> its new commanders
        self.reported: set[tuple[str, object]] = set()
        self.endpoints: dict[Link, Endpoint] = {}
        self.out: list[tuple[int, Finding]] = []  # (target system, finding)

    def add(self, f: Frame, fields: Fields | None) -> None:
        if f.msgid == 0:
            self.heartbeat_seen.add((f.sysid, f.compid))
            if fields is not None and fields.get("type") == MAV_TYPE_GCS:
                self.gcs.add(f.sysid)
            return
        if fields is None or f.msgdef is None or f.msgdef.name not in COMMANDING:
            return
        target = target_of(fields)
        if not isinstance(target, int) or target in self.gcs or target == f.sysid:
            return
        sender = (f.sysid, f.compid)
        name = f.msgdef.name
        est = self.first_commander.setdefault(target, sender)
        if est[0] != sender[0]:
            new = self.commanded.get(target)
            if new is None:
                new = self.commanded[target] = Commanded(est)
            new.add(sender, name, f.record)
        if f.src is not None:
            known = self.endpoints.setdefault(sender, f.src)
            if known != f.src and ("src", (sender, f.src)) not in self.reported:
                self.reported.add(("src", (sender, f.src)))
                self.out.append((target, unexpected_command_source(sender, name, str(f.src), str(known), f.record)))
        if sender not in self.heartbeat_seen and ("hb", sender) not in self.reported:
            self.reported.add(("hb", sender))
            self.out.append((target, command_without_heartbeat(sender, name, target, f.record)))

    def findings(self) -> list[Finding]:
        new = [new_commanders(target, c) for target, c in sorted(self.commanded.items()) if target not in self.gcs]
        return new + [fd for target, fd in self.out if target not in self.gcs]


# CommandSources' findings
def new_commanders(target: int, c: Commanded) -> Finding:
    """The `new-commander` finding of vehicle `target`: its one new commander, or how many and the first."""
    count = c.frames.count
    if count == 1:
        ((sender, name),) = c.shown
        return finding("new-commander", f"system {sender[0]}/{sender[1]} commands system {target} ({name}), which "
                                        f"{c.first[0]}/{c.first[1]} commanded until then", c.frames.nums)
    named = ", ".join(f"{s}/{k} ({name})" for (s, k), name in c.shown)
    more = f" and {count - len(c.shown)} more" if count > len(c.shown) else ""
    return finding("new-commander", f"{count} senders command system {target} after {c.first[0]}/{c.first[1]}, "
                                    f"which commanded it first: {named}{more}", c.frames.nums)


def unexpected_command_source(sender: Link, name: str, src: str, known: str, record: int) -> Finding:
    return finding("unexpected-command-source", f"{name} from {sender[0]}/{sender[1]} arrives from {src}; its "
                                                f"commands came from {known} until then", (record,))


def command_without_heartbeat(sender: Link, name: str, target: int, record: int) -> Finding:
    return finding("command-without-heartbeat", f"{sender[0]}/{sender[1]} sends {name} to system {target} before "
                                                "any HEARTBEAT of its own", (record,))
