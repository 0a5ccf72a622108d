"""The mission protocol state machine: frames in capture order in, a MissionLog out, in bounded state (the
open exchanges, the last HEARTBEAT and HOME_POSITION of each system, a few recent frames per sender).

A transfer opens with a MISSION_COUNT from the system holding the items to the one that will request
them, per mission type (0 mission, 1 fence, 2 rally), or with a MISSION_WRITE_PARTIAL_LIST (items
start..end, as Mission Planner and MAVProxy's `wp move` send it). MISSION_REQUEST(_INT) (either, as
requested) and MISSION_ITEM(_INT) (either, mixed) join it when the mission type matches, it has not been
silent for TRANSFER_TIMEOUT and both ends fit: a target of system or component 0 is a broadcast
(model.same), and the party that answers a COUNT is its receiver whatever the COUNT's target said
(`answers.Answers.answering`: a legacy MAVLink 1 upload to 0/0 answered by system 10; a COUNT to 1/190
answered by PX4's autopilot 1/1). A MISSION_ACK ACCEPTED from the receiver closes it; which operation an
ACK answers is the protocol's state per vehicle (answers.py: the ACK of a MISSION_CLEAR_ALL that arrives
after the next COUNT answers the clear). Any other ACK is a NACK that decides the outcome only if nothing
of the transfer follows it: ArduPilot answers an item out of sequence with MAV_MISSION_INVALID_SEQUENCE
and requests again, PX4 answers a GCS that cannot do MISSION_ITEM_INT with MAV_MISSION_UNSUPPORTED and
switches. A new MISSION_COUNT (or MISSION_REQUEST_LIST) between the same two systems for the same type
restarts the exchange; the same COUNT again before any answer is a retry (Mission Planner's setWPTotal
resends it 3 times at 700 ms, QGroundControl's PlanManager 5 times at its ack timeout).

The direction is `download` when the receiver asked for the items with MISSION_REQUEST_LIST, otherwise it
comes from the HEARTBEATs (a vehicle sending the items: download; a GCS: upload), else from component ids
(the autopilot is component 1). Byte copies of a frame (same MAVLink sequence number, a few frames apart)
are link or capture duplicates: they are counted, never taken for a new transfer.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from typing import cast

from mavscope.analysis.mission.answers import WAITING_MAX, Answers
from mavscope.analysis.mission.describe import reason
from mavscope.analysis.mission.model import (
    OPEN_MAX,
    TRANSFER_TIMEOUT,
    Addr,
    Event,
    Item,
    MissionLog,
    Transfer,
    broadcast,
    heartbeat_of,
    role,
    same,
)
from mavscope.analysis.mission.state import (
    LISTED_MAX,
    Deadlines,
    Timed,
    listed,
    narrow,
    newest_young,
    open_events,
    open_transfers,
    party,
)
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload
from mavscope.mavlink.semantics import int_coordinate
from mavscope.notes import GivenUp, pop_newest

MISSION_MESSAGES = frozenset({"MISSION_COUNT", "MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ITEM",
                              "MISSION_ITEM_INT", "MISSION_ACK", "MISSION_REQUEST_LIST", "MISSION_CLEAR_ALL",
                              "MISSION_SET_CURRENT", "MISSION_WRITE_PARTIAL_LIST"})
# Every message the reconstruction reads: the mission protocol, MISSION_CURRENT (the answer to
# MISSION_SET_CURRENT), HEARTBEAT (who is a vehicle), HOME_POSITION (the plan's home).
TRACKED_MESSAGES = MISSION_MESSAGES | {"MISSION_CURRENT", "HEARTBEAT", "HOME_POSITION"}
DUPLICATE_WINDOW = 2.0  # seconds: a byte copy later than this is a new transmission (the seq wrapped)
DUPLICATE_FRAMES = 64  # frames of the sender: a byte copy further back is a new transmission
RECENT = 8  # mission frames remembered per sender for duplicate detection
RECENTLY_CLOSED = 16  # closed transfers kept for late frames when the capture has no times
ORPHANS_ACTIVE = 1024  # stray-frame events still gathering frames (the oldest stops first; it stays listed)


def _num(fields: dict[str, object], name: str, default: int = 0) -> int:
    value = fields.get(name, default)
    return int(value) if isinstance(value, (int, float)) else default


def _item(name: str, fields: dict[str, object], record: int) -> Item:
    num = cast("dict[str, float]", fields)  # every MISSION_ITEM(_INT) field is a number (int or float)
    frame = int(num.get("frame", 0))
    x, y = num.get("x", 0), num.get("y", 0)
    if name == "MISSION_ITEM_INT":
        x, y = int_coordinate(int(x), frame), int_coordinate(int(y), frame)
    return Item(int(num["seq"]), int(num["command"]), frame,
                (float(num["param1"]), float(num["param2"]), float(num["param3"]), float(num["param4"])),
                float(x), float(y), float(num.get("z", 0.0)),
                int(num.get("current", 0)), int(num.get("autocontinue", 1)), name, [record])


class MissionTracker(Answers):
    """Feed frames in capture order (`feed`), then `finish()` for the MissionLog."""

    def __init__(self, dialect: Dialect) -> None:
        super().__init__()
        self.dialect = dialect
        self.transfers: list[Transfer] = []
        self.events: list[Event] = []
        self.open = open_transfers()
        self.closed: deque[Transfer] = deque(maxlen=RECENTLY_CLOSED)
        self.lists: dict[tuple[Addr, int, int], Event] = {}  # (asker, target sysid, type) -> REQUEST_LIST
        self.listed = open_events()  # the same REQUEST_LIST events, indexed
        self.clears = open_events()
        self.deadlines = Deadlines(TRANSFER_TIMEOUT)  # what is followed, by how long it has been silent
        self.set_current: dict[int, Event] = {}  # target sysid -> MISSION_SET_CURRENT awaiting MISSION_CURRENT
        self.orphans: dict[tuple[Addr, Addr, int], Event] = {}
        self.heartbeats: dict[Addr, tuple[int, int]] = {}
        self.homes: dict[int, tuple[float, float, float]] = {}
        self.counts: dict[Addr, int] = {}  # frames per sender (all messages)
        self.recent: dict[Addr, deque[tuple[bytes, int, float | None, object]]] = {}
        self.duplicates = 0
        self.now: float | None = None
        self.order = 0
        self.young: dict[int, Transfer] = {}  # open transfers by order, some not yet answered (OPEN_MAX's first)
        self.given_up = GivenUp(f"mission exchanges followed (at most {OPEN_MAX:,} transfers open, {WAITING_MAX:,} "
                                f"requests awaiting an answer, {LISTED_MAX:,} transfers and operations listed)",
                                "exchanges")

    # -- input ---------------------------------------------------------------------------------------

    def feed(self, f: Frame, fields: dict[str, object] | None = None) -> None:
        """`fields`: the frame's payload where the caller has decoded it already (so it is not decoded twice)."""
        md = f.msgdef
        if md is None or f.crc_status is not CrcStatus.OK:
            return
        me = (f.sysid, f.compid)
        n = self.counts[me] = self.counts.get(me, 0) + 1
        if f.time is not None:
            self.now = f.time
        name = md.name
        if name not in TRACKED_MESSAGES:
            return
        if fields is None:
            fields = decode_payload(f)
        if fields is None:
            return
        if name == "HEARTBEAT":
            self.heartbeats[me] = (_num(fields, "type"), _num(fields, "autopilot"))
            return
        if name == "HOME_POSITION":
            self.homes[f.sysid] = (_num(fields, "latitude") / 1e7, _num(fields, "longitude") / 1e7,
                                   _num(fields, "altitude") / 1000)
            return
        self._expire(f.time)
        if name == "MISSION_CURRENT":
            self._mission_current(f, _num(fields, "seq"))
            return
        recent = self.recent.setdefault(me, deque(maxlen=RECENT))
        for raw, n0, t0, owner in recent:
            if raw == f.raw and n - n0 <= DUPLICATE_FRAMES and (t0 is None or f.time is None
                                                                  or f.time - t0 <= DUPLICATE_WINDOW):
                self.duplicates += 1
                if isinstance(owner, Transfer):
                    owner.duplicates.append(f.record)
                elif isinstance(owner, Event):
                    owner.frames.append(f.record)
                return
        tgt = (_num(fields, "target_system"), _num(fields, "target_component"))
        mtype = _num(fields, "mission_type")
        owner = self._dispatch(f, name, fields, me, tgt, mtype)
        recent.append((f.raw, n, f.time, owner))
        if isinstance(owner, (Transfer, Event)):  # the one object a frame can have touched (its `last`)
            self.deadlines.push(owner)
            self.deadlines.compact(len(self.open) + len(self.lists) + len(self.clears) + len(self.set_current)
                                   + len(self.orphans), self._followed)

    def _dispatch(self, f: Frame, name: str, fields: dict[str, object], me: Addr, tgt: Addr,
                  mtype: int) -> object:
        if name == "MISSION_COUNT":
            return self._count(f, me, tgt, mtype, _num(fields, "count"))
        if name == "MISSION_WRITE_PARTIAL_LIST":
            start, end = _num(fields, "start_index"), _num(fields, "end_index")
            return self._count(f, me, tgt, mtype, end + 1 if end >= start >= 0 else max(start, 0), max(start, 0))
        if name == "MISSION_REQUEST_LIST":
            return self._request_list(f, me, tgt, mtype)
        if name in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
            return self._request(f, name, me, tgt, mtype, _num(fields, "seq"))
        if name in ("MISSION_ITEM", "MISSION_ITEM_INT"):
            return self._item(f, name, fields, me, tgt, mtype)
        if name == "MISSION_ACK":
            return self._ack(f, me, tgt, mtype, _num(fields, "type"))
        if name == "MISSION_CLEAR_ALL":
            return self._clear_all(f, me, tgt, mtype)
        return self._set_current(f, me, tgt, _num(fields, "seq"))  # MISSION_SET_CURRENT

    # -- time ----------------------------------------------------------------------------------------

    def _stale(self, last: float | None, now: float | None) -> bool:
        return last is not None and now is not None and now - last > TRANSFER_TIMEOUT

    def _followed(self) -> list[Timed]:
        return [*self.open, *self.lists.values(), *self.clears, *self.set_current.values(), *self.orphans.values()]

    def _live(self, x: Timed) -> bool:
        """Whether `x` is still followed (a transfer open, an event awaiting its answer or more frames)."""
        if isinstance(x, Transfer):
            return x in self.open
        ev = cast("Event", x)
        if ev.kind == "request-list":
            return self.lists.get((ev.sender, ev.target[0], ev.mission_type)) is ev
        if ev.kind == "clear-all":
            return ev in self.clears
        if ev.kind == "set-current":
            return self.set_current.get(ev.target[0]) is ev
        return ev.kind == "orphan" and self.orphans.get((ev.sender, ev.target, ev.mission_type)) is ev

    def _expire(self, now: float | None) -> None:
        """Close what has been silent for longer than TRANSFER_TIMEOUT (transfers in the order they opened)."""
        if now is None:
            return
        due = self.deadlines.due(now, self._live)
        for t in sorted((x for x in due if isinstance(x, Transfer)), key=lambda t: t.order):
            self._close(t, "timeout")
        for ev in (x for x in due if isinstance(x, Event)):
            if ev.kind == "request-list":
                self._unlist(ev)
                if not ev.answered_by:  # a broadcast one some vehicle answered is in its downloads
                    self._event(ev)
            elif ev.kind == "clear-all":
                self.clears.remove(ev)
            elif ev.kind == "set-current":
                self._settle(self.set_current.pop(ev.target[0]))
            else:
                del self.orphans[(ev.sender, ev.target, ev.mission_type)]

    def _unlist(self, ev: Event) -> None:
        del self.lists[(ev.sender, ev.target[0], ev.mission_type)]
        self.listed.remove(ev)

    def _close(self, t: Transfer, how: str) -> None:
        t.close(how)
        self.open.remove(t)
        self.closed.append(t)

    def _event(self, ev: Event) -> Event:
        self.events.append(ev)
        listed(self.events, "a mission operation", self.given_up)
        return ev

    def _new_event(self, kind: str, f: Frame, me: Addr, tgt: Addr, mtype: int) -> Event:
        self.order += 1
        return Event(kind, me, tgt, mtype, f.time, self.order, [f.record], last=f.time)

    # -- transfers -----------------------------------------------------------------------------------

    def _find(self, mtype: int, sender: Addr, receiver: Addr) -> Transfer | None:
        """The latest open transfer of `mtype` from `sender` to `receiver`."""
        return self.open.latest(mtype, sender, receiver)

    def _late(self, f: Frame, mtype: int, a: Addr, b: Addr) -> Transfer | None:
        """A transfer between `a` and `b` that ended shortly before `f` (its frames may still trickle in)."""
        for t in reversed(self.closed):
            if t.mission_type == mtype and ((same(t.sender, a) and same(t.receiver, b))
                                            or (same(t.sender, b) and same(t.receiver, a))):
                if (t.last is None and f.time is None) or (t.last is not None and f.time is not None
                                                           and f.time - t.last <= TRANSFER_TIMEOUT):
                    return t
                return None
        return None

    def _count(self, f: Frame, me: Addr, tgt: Addr, mtype: int, count: int, first: int | None = None) -> Transfer:
        """A MISSION_COUNT (`first` None) or a MISSION_WRITE_PARTIAL_LIST of items `first`..`count`-1."""
        partial = first is not None
        t = self._find(mtype, me, tgt)
        if (t is not None and t.count == count and t.partial == partial and t.first == (first or 0)
                and not t.answered and t.addressed == tgt):
            t.count_resent += 1  # the same COUNT again: the receiver did not answer yet
            t.touch(f.record, f.time)
            t.opened = len(t.frames)
            return t
        for old in self.open.between(mtype, me, tgt):
            self._close(old, "restarted")
        self.order += 1
        t = Transfer(me, tgt, mtype, count, f.time, self.order, addressed=tgt, first=first or 0, partial=partial)
        # the first REQUEST_LIST of this type to this system (any component) from the COUNT's target
        ev = None if partial else self.listed.first(mtype, tgt, (me[0], 0))
        if ev is not None:
            if ev.addressed is not None and broadcast(ev.addressed):  # other vehicles may answer it too
                if len(ev.answered_by) < 64:
                    ev.answered_by.append(me)
            else:
                self._unlist(ev)
            t.direction, t.direction_basis, t.receiver = "download", "request-list", ev.sender
            t.frames.extend(ev.frames)
        t.touch(f.record, f.time)
        t.opened = len(t.frames)
        if broadcast(t.receiver):
            self.families.pop((me, mtype), None)
            self.families[(me, mtype)] = self.last_family[mtype] = [t]
            if len(self.families) > OPEN_MAX:  # the newest broadcast COUNT but this one takes no more answerers
                _, (gone, *_) = pop_newest(self.families, (me, mtype))
                self.given_up.add(f"the broadcast MISSION_COUNT of {party(gone.sender)} (frame {gone.frames[0]}) "
                                  "takes no more answerers (theirs shown as orphans)", record=f.record)
        self.adopt(t)
        return t

    def adopt(self, t: Transfer) -> None:
        """Follow a new transfer. Past OPEN_MAX open, the newest not yet answered but `t` is given up (a flood
        of COUNTs churns its own; an exchange under way stays), else `t` itself."""
        self.transfers.append(t)
        listed(self.transfers, "a mission transfer", self.given_up)
        self.open.add(t)
        self.deadlines.push(t)
        if len(self.open) > OPEN_MAX:
            victim = newest_young(self.young, self.open) or t
            self._close(victim, "evicted")
            self.given_up.add(f"the transfer of {victim.count} items {party(victim.sender)} -> "
                              f"{party(victim.addressed or victim.receiver)} (frame {victim.frames[0]}) given up "
                              "unanswered", record=t.frames[-1])
        if t in self.open:
            self.young[t.order] = t

    def _request_list(self, f: Frame, me: Addr, tgt: Addr, mtype: int) -> object:
        for old in self.open.matching(mtype, tgt, me):
            if not old.requests and not old.items and not old.acks:
                old.touch(f.record, f.time)  # asked again before requesting anything: the COUNT was lost
                return old
            self._close(old, "restarted")  # asking again restarts the download
        key = (me, tgt[0], mtype)
        ev = self.lists.get(key)
        if ev is None:
            ev = self.lists[key] = self._new_event("request-list", f, me, tgt, mtype)
            ev.addressed = tgt
            self.listed.add(ev)
            self.wait_bound(ev, key)
        else:
            ev.frames.append(f.record)
            ev.last = f.time
        return ev

    def _continue(self, t: Transfer, f: Frame) -> None:
        """A frame of the transfer after a NACK: the parties went on, so the NACK was not the end."""
        if t.pending is not None:
            t.pending.role = "continued"
            t.pending = None
        t.touch(f.record, f.time)

    def _request(self, f: Frame, name: str, me: Addr, tgt: Addr, mtype: int, seq: int) -> object:
        found, how = self.answering(f, mtype, tgt, me)
        if found is None:
            return self._stray(f, name, me, tgt, mtype, seq)
        t = self.take(found, how, me)
        self._continue(t, f)
        t.requests.append(seq)
        t.max_request = max(t.max_request, seq)
        return t

    def _item(self, f: Frame, name: str, fields: dict[str, object], me: Addr, tgt: Addr, mtype: int) -> object:
        seq = _num(fields, "seq")
        # A broadcast item reaches every party answering the broadcast COUNT (at most MAX_FORKS); an
        # addressed one its party
        fam = [t for t in self.families.get((me, mtype), ()) if t in self.open] if broadcast(tgt) else []
        latest = self.holding(mtype, me, tgt)
        found = fam or ([latest] if latest is not None else [])
        if not found:
            return self._stray(f, name, me, tgt, mtype, seq)
        for t in found:
            if broadcast(t.receiver) and not broadcast(tgt):
                narrow(self.open, t, tgt)  # no answer in the capture: the items name the receiver
            self._continue(t, f)
            self._add_item(t, _item(name, fields, f.record), seq)
            if t is not found[-1]:
                self.deadlines.push(t)
        return found[-1]

    def _add_item(self, t: Transfer, item: Item, seq: int) -> None:
        old = t.items.get(seq)
        if old is None:
            t.items[seq] = item
            return
        t.resent[seq] = t.resent.get(seq, 0) + 1
        if old.content() != item.content():
            t.resent_changed.add(seq)
        if t.max_request > seq:  # the receiver had moved on: this copy answers nothing, the earlier one stays
            old.frames.append(item.frames[0])
        else:  # a copy the receiver asked for again: it replaces the earlier one
            old.frames.extend(item.frames)  # in place: a copy per resend was quadratic in the resends
            item.frames = old.frames
            t.items[seq] = item

    def _stray(self, f: Frame, name: str, me: Addr, tgt: Addr, mtype: int, seq: int) -> object:
        late = self._late(f, mtype, me, tgt)
        if late is not None:
            late.late_frames.append(f.record)
            return late
        key = (me, tgt, mtype)
        ev = self.orphans.get(key)
        if ev is None:
            ev = self.orphans[key] = self._event(self._new_event("orphan", f, me, tgt, mtype))
            if len(self.orphans) > ORPHANS_ACTIVE:
                del self.orphans[next(iter(self.orphans))]
        else:
            ev.frames.append(f.record)
            ev.last = f.time
        ev.messages[name] = ev.messages.get(name, 0) + 1
        if len(ev.seqs) < 1000:
            ev.seqs.append(seq)
        return ev

    # -- other operations ----------------------------------------------------------------------------

    def _clear_all(self, f: Frame, me: Addr, tgt: Addr, mtype: int) -> Event:
        ev = self.clears.first(mtype, me, tgt, exact_sender=True)
        if ev is not None and ev.addressed == tgt:
            ev.frames.append(f.record)  # sent again: no answer yet
            ev.last = f.time
            return ev
        ev = self._event(self._new_event("clear-all", f, me, tgt, mtype))
        ev.addressed = tgt
        self.clears.add(ev)
        self.wait_bound(ev)
        return ev

    def _set_current(self, f: Frame, me: Addr, tgt: Addr, seq: int) -> Event:
        previous = self.set_current.pop(tgt[0], None)
        if previous is not None:
            self._settle(previous)
        ev = self._event(self._new_event("set-current", f, me, tgt, 0))
        ev.seq = seq
        self.set_current[tgt[0]] = ev
        return ev

    def _mission_current(self, f: Frame, seq: int) -> None:
        key = f.sysid if f.sysid in self.set_current else 0  # 0: a MISSION_SET_CURRENT to every system
        ev = self.set_current.get(key)
        if ev is None:
            return
        ev.reported, ev.reply_frame = seq, f.record
        if seq == ev.seq:
            ev.confirmed = True
            del self.set_current[key]

    def _settle(self, ev: Event) -> None:
        if ev.confirmed is None and ev.reported is not None:
            ev.confirmed = False

    # -- output --------------------------------------------------------------------------------------

    def finish(self) -> MissionLog:
        for t in self.open:
            self._close(t, "timeout" if self._stale(t.last, self.now) else "end")
        for ev in self.lists.values():
            if not ev.answered_by:
                self._event(ev)
        self.lists.clear()
        self.listed = open_events()
        for ev in self.set_current.values():
            self._settle(ev)
        self.set_current.clear()
        self.events.sort(key=lambda ev: ev.order)
        systems = {a[0] for a in self.counts}
        for t in self.transfers:  # `same` with any sender, in a few lookups
            r = t.receiver
            t.receiver_silent = not (r in self.counts or (r[0], 0) in self.counts if r[1] else r[0] in systems)
            if not t.direction:
                t.direction, t.direction_basis = self._direction(t)
            t.reason = reason(t, self.dialect)
        return MissionLog(self.transfers, self.events, dict(self.heartbeats), dict(self.homes), self.duplicates,
                          self.given_up.finding())

    def _direction(self, t: Transfer) -> tuple[str, str]:
        """Upload or download from who is a vehicle: the sender's HEARTBEAT, else the receiver's."""
        for addr, if_vehicle, if_gcs in ((t.sender, "download", "upload"), (t.receiver, "upload", "download")):
            hb = self.heartbeats.get(addr)
            if hb is not None and role(hb) in ("vehicle", "gcs"):
                return (if_vehicle if role(hb) == "vehicle" else if_gcs), "heartbeat"
        for addr, if_vehicle in ((t.sender, "download"), (t.receiver, "upload")):
            hb = heartbeat_of(self.heartbeats, addr)
            if hb is not None and role(hb) == "vehicle" and addr[1] in (0, 1):
                return if_vehicle, "heartbeat"
        if t.sender[1] == 1:
            return "download", "component-id"  # MAV_COMP_ID_AUTOPILOT1 holds the items
        if t.receiver[1] == 1:
            return "upload", "component-id"
        return "unknown", "none"


def analyse(frames: Iterable[Frame], dialect: Dialect) -> MissionLog:
    """Every mission transfer and operation of `frames` (all frames of a capture, in capture order)."""
    tracker = MissionTracker(dialect)
    for f in frames:
        tracker.feed(f)
    return tracker.finish()


def reconstruct(frames: Iterable[Frame], dialect: Dialect) -> list[Transfer]:
    """Every mission transfer of the capture, in the order they started."""
    return analyse(frames, dialect).transfers
