"""Which operation a MISSION_ACK answers, and the operations answered only by one (MISSION_CLEAR_ALL, a
refused MISSION_REQUEST_LIST), paired by the protocol's state per vehicle rather than by the latest start.

A mission server (the vehicle) handles the messages of a link in the order they arrive and answers each
before the next (ArduPilot's GCS_MAVLINK::handle_message and MissionItemProtocol, PX4's
MavlinkMissionManager::handle_message). Ground stations do not wait for every answer: Mission Planner and
MAVProxy's old wp module send MISSION_CLEAR_ALL and then MISSION_COUNT, so the ACK of the clear arrives
after the COUNT; ArduPilot before 3.x sent the ACK of a clear three times. So an ACK answers the oldest
operation, between these two parties and of this mission type, that can take that answer now:

- an upload takes MAV_MISSION_ACCEPTED only once something beyond its MISSION_COUNT happened (the vehicle
  requested an item, an item went out) or when it has no items (count 0, the spec's "clear by upload");
  an error it takes at any time (MAV_MISSION_NO_SPACE, DENIED to a second GCS, INVALID_SEQUENCE...);
- a MISSION_CLEAR_ALL takes any answer (for its mission type, or MAV_MISSION_TYPE_ALL);
- a MISSION_REQUEST_LIST takes an ACK only as a refusal.

An operation the vehicle left unanswered while answering a later one of the same party is over
(`supersede`): its ACK can no longer come. An ACCEPTED that fits nothing waiting is the same ACK again when
it repeats the answer to a clear just before; else, as a last resort, the ACK of an upload whose items the
capture lost. Targets of system or component 0 are broadcasts (model.same); whoever answers one is its
receiver, and a second vehicle answering the same broadcast gets an exchange of its own (`fork`).
"""

from __future__ import annotations

from collections import deque
from typing import cast

from mavscope.analysis.mission.model import (
    MAV_MISSION_ACCEPTED,
    MAV_MISSION_TYPE_ALL,
    TRANSFER_TIMEOUT,
    Ack,
    Addr,
    Event,
    Transfer,
    broadcast,
    same,
)
from mavscope.analysis.mission.state import Deadlines, PartyIndex, narrow, party, retarget
from mavscope.mavlink.frame import Frame
from mavscope.notes import GivenUp, pop_newest

ANSWERED_KEPT = 16  # answered clears remembered for the repeats of their ACK and other answerers of a broadcast
MAX_FORKS = 16  # parties answering one broadcast MISSION_COUNT or MISSION_CLEAR_ALL each get their own exchange
WAITING_MAX = 1024  # REQUEST_LISTs awaiting their COUNT, and CLEAR_ALLs their ACK (more: the newest but the new
# one is no longer followed, listed unanswered; said as `capacity`)


def recent(t_last: float | None, now: float | None) -> bool:
    """Whether something last active at `t_last` is recent enough at `now` for a frame to belong to it."""
    return (t_last is None and now is None) or (t_last is not None and now is not None
                                                and now - t_last <= TRANSFER_TIMEOUT)


class Answers:
    """The ACK side of MissionTracker (a mixin: the attributes are the tracker's)."""

    open: PartyIndex[Transfer]
    clears: PartyIndex[Event]
    listed: PartyIndex[Event]
    deadlines: Deadlines
    events: list[Event]
    order: int
    lists: dict[tuple[Addr, int, int], Event]
    given_up: GivenUp

    def wait_bound(self, ev: Event, key: object = None) -> None:
        """Past WAITING_MAX REQUEST_LISTs (`key` in `lists`) or CLEAR_ALLs awaiting an answer, the newest but
        `ev` is no longer awaited (listed unanswered; its answer, if it comes, is shown apart)."""
        if ev.kind == "request-list":
            if len(self.lists) <= WAITING_MAX:
                return
            _, old = pop_newest(self.lists, key)
            self.listed.remove(old)
            self._event(old)
        else:
            if len(self.clears) <= WAITING_MAX:
                return
            old = self.clears.newest_but(ev)
            self.clears.remove(old)
        self.given_up.add(f"a {old.kind} of {party(old.sender)} (frame {old.frames[0]}) no longer awaited: its "
                          "answer would be shown apart", record=ev.frames[-1])

    # the tracker's own (reconstruct.MissionTracker)
    def adopt(self, t: Transfer) -> None:
        raise NotImplementedError

    def _close(self, t: Transfer, how: str) -> None:
        raise NotImplementedError

    def _unlist(self, ev: Event) -> None:
        raise NotImplementedError

    def _late(self, f: Frame, mtype: int, a: Addr, b: Addr) -> Transfer | None:
        raise NotImplementedError

    def _new_event(self, kind: str, f: Frame, me: Addr, tgt: Addr, mtype: int) -> Event:
        raise NotImplementedError

    def _event(self, ev: Event) -> Event:
        raise NotImplementedError

    def __init__(self) -> None:
        self.answered_clears: deque[Event] = deque(maxlen=ANSWERED_KEPT)
        self.families: dict[tuple[Addr, int], list[Transfer]] = {}  # (sender, type) -> one broadcast COUNT's transfers
        self.last_family: dict[int, list[Transfer]] = {}  # type -> the latest of them

    # -- who is answering what -----------------------------------------------------------------------

    def answering(self, f: Frame, mtype: int, tgt: Addr, me: Addr) -> tuple[Transfer | None, str]:
        """The open transfer whose receiver `me` is answering (a request or an ACK to `tgt`, its sender),
        and how it was found: "target" (the COUNT's target is `me`, or a broadcast no one else answered),
        "fork" (another party answered the broadcast first: `me` received it too), "answerer" (no target
        fits: the party that answers is the one that received, whatever the target said), "" (none)."""
        t = self.open.latest(mtype, tgt, me)
        if t is not None and t.sender != me:  # (a broadcast target fits `me`'s own transfers too: not those)
            return t, "target"
        family = self.families.get((tgt, mtype)) if not broadcast(tgt) else self.last_family.get(mtype)
        if family:
            first = family[0]
            if (first.addressed is not None and same(first.addressed, me) and same(first.sender, tgt)
                    and first.sender != me and all(x.receiver != me for x in family) and len(family) < MAX_FORKS
                    and (first in self.open or recent(first.last, f.time))):
                return first, "fork"
        if not broadcast(tgt):
            t = self.open.latest(mtype, tgt, (0, 0))
            if t is not None and t.sender != me and not t.answered and t.receiver != me:
                return t, "answerer"
        return None, ""

    def holding(self, mtype: int, me: Addr, tgt: Addr) -> Transfer | None:
        """The open transfer `me` holds the items of, that a frame of `me` to `tgt` belongs to: the latest
        whose receiver `tgt` fits, else the latest addressed as `tgt` (the COUNT went to 1/190, PX4's
        autopilot 1/1 answered, the items still go to 1/190)."""
        t = self.open.latest(mtype, me, tgt, exact_sender=True)
        if t is None:
            t = self.open.latest(mtype, me, (0, 0), exact_sender=True)
            if t is not None and t.addressed != tgt:
                t = None
        return t

    def take(self, t: Transfer, how: str, me: Addr) -> Transfer:
        """The transfer `me` answers, `answering`'s choice applied: a fork made, the receiver narrowed."""
        if how == "fork":
            t = self.fork(t, me)
        elif t.receiver != me:
            narrow(self.open, t, me)
        self.supersede(t, me)
        return t

    def fork(self, first: Transfer, me: Addr) -> Transfer:
        """A transfer of its own for a second party answering a broadcast MISSION_COUNT."""
        self.order += 1
        t = Transfer(first.sender, me, first.mission_type, first.count, first.start, self.order,
                     addressed=first.addressed, first=first.first, partial=first.partial,
                     direction=first.direction, direction_basis=first.direction_basis)
        t.frames = first.frames[:first.opened]  # its MISSION_COUNT (and the copies sent before any answer)
        t.opened, t.count_resent = first.opened, first.count_resent
        t.last = t.end = first.start
        self.families[(first.sender, first.mission_type)].append(t)
        self.adopt(t)
        return t

    def supersede(self, t: Transfer, me: Addr) -> None:
        """`me` answered `t`: the clears and list requests its sender sent `me` before `t` began are over
        (the vehicle answers in order: their answer would have come first)."""
        for mtype in {t.mission_type, MAV_MISSION_TYPE_ALL}:
            for ev in self.clears.matching(mtype, t.sender, me):
                if ev.order < t.order and ev.sender == t.sender:
                    self.clears.remove(ev)

    # -- MISSION_ACK ---------------------------------------------------------------------------------

    def _ack(self, f: Frame, me: Addr, tgt: Addr, mtype: int, result: int) -> object:
        ack = Ack(me, result, f.record, f.time)
        receiving, how = self.answering(f, mtype, tgt, me)
        waiting: list[tuple[int, object]] = []  # what can take this answer now, by when it began
        if receiving is not None and (result != MAV_MISSION_ACCEPTED or receiving.count <= receiving.first
                                      or receiving.answered):
            waiting.append((receiving.order, receiving))
        for m in {mtype, MAV_MISSION_TYPE_ALL}:
            ev = self.clears.first(m, tgt, me)
            if ev is not None:
                waiting.append((ev.order, ev))
        listed = self.listed.first(mtype, tgt, me)
        if listed is not None and result != MAV_MISSION_ACCEPTED:
            waiting.append((listed.order, listed))
        if waiting:
            target = min(waiting, key=lambda c: c[0])[1]
            if isinstance(target, Event):
                return self._event_answered(target, ack, f, me)
            return self._receiver_ack(self.take(cast("Transfer", target), how, me), ack, f)
        sending = self.holding(mtype, me, tgt)
        if sending is not None:
            return self._sender_ack(sending, ack, f)
        again = self._answered_clear(f, mtype, tgt, me)
        if again is not None:
            return self._clear_again(again, ack, f, me)
        if receiving is not None:  # ACCEPTED though nothing of the exchange is in the capture
            return self._receiver_ack(self.take(receiving, how, me), ack, f)
        return self._unexplained(f, ack, me, tgt, mtype)

    def _receiver_ack(self, t: Transfer, ack: Ack, f: Frame) -> Transfer:
        t.acks.append(ack)
        t.touch(f.record, f.time)
        if ack.result == MAV_MISSION_ACCEPTED:
            t.result = ack.result
            if t.pending is not None:
                t.pending.role = "continued"
            t.pending = None
            self._close(t, "ack")
        else:
            if t.pending is not None:
                t.pending.role = "repeated"
            t.pending = ack
        return t

    def _sender_ack(self, t: Transfer, ack: Ack, f: Frame) -> Transfer:
        """The holder of the items ends the exchange (a cancel; PX4 ends a download it cannot serve)."""
        t.acks.append(ack)
        t.touch(f.record, f.time)
        if t.pending is not None:
            t.pending.role = "repeated"
        t.pending = ack
        return t

    def _event_answered(self, ev: Event, ack: Ack, f: Frame, me: Addr) -> Event:
        ev.ack = ack
        ev.frames.append(f.record)
        ev.last = f.time
        if ev.kind == "clear-all":
            self.clears.remove(ev)
            retarget(self.clears, ev, me)
            self.answered_clears.append(ev)
            return ev
        self._unlist(ev)  # a MISSION_REQUEST_LIST refused with an ACK instead of a COUNT
        self.events.append(ev)
        return ev

    def _answered_clear(self, f: Frame, mtype: int, tgt: Addr, me: Addr) -> Event | None:
        """A clear answered shortly before by `me` with this result (its ACK again), or a broadcast clear
        another party answered (`me` answers it too)."""
        for ev in reversed(self.answered_clears):
            if ev.mission_type in (mtype, MAV_MISSION_TYPE_ALL) and same(ev.sender, tgt) and recent(ev.last, f.time):
                if ev.target == me or (ev.addressed is not None and broadcast(ev.addressed) and same(ev.addressed, me)):
                    return ev
        return None

    def _clear_again(self, ev: Event, ack: Ack, f: Frame, me: Addr) -> Event:
        if ev.target == me:
            ack.role = "repeated"
            ev.repeats.append(ack)
            ev.frames.append(f.record)
            ev.last = f.time
            return ev
        self.order += 1  # another vehicle answering the same broadcast clear: a clear of its own
        twin = Event("clear-all", ev.sender, me, ev.mission_type, ev.time, self.order, [ev.frames[0]], ack=ack,
                     last=f.time, addressed=ev.addressed)
        twin.frames.append(f.record)
        self.events.append(twin)
        self.answered_clears.append(twin)
        return twin

    def _unexplained(self, f: Frame, ack: Ack, me: Addr, tgt: Addr, mtype: int) -> object:
        late = self._late(f, mtype, me, tgt)
        if late is not None:
            ack.role = "late"
            late.acks.append(ack)
            late.late_frames.append(f.record)
            return late
        ev = self._new_event("unmatched-ack", f, me, tgt, mtype)
        ev.ack = ack
        return self._event(ev)
