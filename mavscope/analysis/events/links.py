"""Event sources about the links: signing (who signs, on which link ids, signers that send unsigned
frames, SETUP_SIGNING, signatures the security layer judged invalid or replayed) and link loss (a sender
that falls silent for longer than its heartbeats allow, and is heard again)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from mavscope.analysis.events.model import LINK, SIGNING, Addr, Event, Fields, addr, at
from mavscope.analysis.vehicles import MAX_SENDERS
from mavscope.mavlink.frame import Frame, SignatureStatus

LINK_TIMEOUT = 5.0  # s of silence at least before a sender counts as lost (ArduPilot's FS_GCS_TIMEOUT default)
HEARTBEATS_MISSED = 3.0  # ...and at least this many of its heartbeat periods
EMA = 0.2  # weight of the newest heartbeat interval in the running estimate of the period


class Signing:
    """Per sender: its first signed frame on each link id, its unsigned frames once it signs (one event, at
    the first, with their number), frames whose signature the security layer found invalid or replayed (one
    event per sender and verdict, at the first); SETUP_SIGNING frames (the key itself is never shown). Every
    table is keyed by sender (the links a sender signs on: one 256-bit mask), so none fills (MAX_SENDERS:
    every pair): a flood of made-up signers cannot hide the vehicle's signing."""

    wants = frozenset({"SETUP_SIGNING"})

    def __init__(self) -> None:
        self.signers: dict[Addr, int] = {}  # sender -> the link ids it signs on (bit i: link i)
        self.unsigned: dict[Addr, tuple[Frame, int]] = {}
        self.verdicts: dict[tuple[Addr, str], tuple[Frame, int]] = {}  # (at most 2 a sender)

    def _count(self, table: dict[Any, tuple[Frame, int]], key: object, f: Frame) -> None:
        entry = table.get(key)
        table[key] = (f, 1) if entry is None else (entry[0], entry[1] + 1)

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        me = (f.sysid, f.compid)
        out: list[Event] = []
        sig = f.signature
        if sig is not None:
            links = self.signers.get(me, 0)
            if not links >> sig.link_id & 1:
                first = not links
                self.signers[me] = links | 1 << sig.link_id
                out.append(at(f, SIGNING, f"{addr(me)} signs its frames on link {sig.link_id}" if first else
                              f"{addr(me)} also signs on link {sig.link_id}", what="signed", link_id=sig.link_id))
            status = f.signature_status
            if status in (SignatureStatus.INVALID, SignatureStatus.REPLAY):
                self._count(self.verdicts, (me, status.value), f)
        elif me in self.signers:
            self._count(self.unsigned, me, f)
        if fields is not None:
            ts, tc = fields.get("target_system"), fields.get("target_component")
            to = (ts, tc) if isinstance(ts, int) and isinstance(tc, int) else None
            out.append(at(f, SIGNING, f"{addr(me)} sends SETUP_SIGNING{' to ' + addr(to) if to else ''}: a signing "
                                      "key in clear", to, what="setup-signing"))
        return out

    def finish(self) -> Iterable[Event]:
        out = [at(f, SIGNING, f"{addr((f.sysid, f.compid))} sends {n} unsigned frame(s) although it signs",
                  what="unsigned", frames=n) for f, n in self.unsigned.values()]
        out += [at(f, SIGNING, f"{addr(me)}: {n} frame(s) with a{'n' if verdict == 'invalid' else ''} "
                               f"{verdict} signature", what=verdict, frames=n)
                for (me, verdict), (f, n) in self.verdicts.items()]
        return out


class _Sender:
    __slots__ = ("last_time", "last_frame", "heartbeats", "last_heartbeat", "period")

    def __init__(self, f: Frame, t: float) -> None:
        self.last_time = t
        self.last_frame = f
        self.heartbeats = 0
        self.last_heartbeat: float | None = None
        self.period = 1.0

    @property
    def timeout(self) -> float:
        return max(LINK_TIMEOUT, HEARTBEATS_MISSED * self.period)


class LinkHealth:
    """A sender that has sent HEARTBEATs (so is expected to keep talking) and then is not heard for longer
    than max(LINK_TIMEOUT, HEARTBEATS_MISSED heartbeat periods): `link` lost, dated by its last frame, and
    recovered, dated by its next; silent until the end of the capture: lost, without recovery. Capture
    time is the clock; a capture without times has no link events."""

    wants: frozenset[str] = frozenset()

    def __init__(self) -> None:
        self.senders: dict[Addr, _Sender] = {}
        self.end: float | None = None

    def add(self, f: Frame, fields: Fields | None) -> Iterable[Event]:
        t = f.time
        if t is None:
            return ()
        if self.end is None or t > self.end:
            self.end = t
        me = (f.sysid, f.compid)
        s = self.senders.get(me)
        if s is None:
            if len(self.senders) < MAX_SENDERS:
                s = self.senders[me] = _Sender(f, t)
                if f.msgid == 0:
                    s.heartbeats, s.last_heartbeat = 1, t
            return ()
        out: list[Event] = []
        gap = t - s.last_time
        if s.heartbeats >= 2 and gap > s.timeout:
            last = s.last_frame
            out.append(at(last, LINK, f"{addr(me)} falls silent: nothing from it for {gap:.1f} s", what="lost",
                          silent_s=round(gap, 3)))
            out.append(at(f, LINK, f"{addr(me)} is heard again after {gap:.1f} s", what="recovered",
                          silent_s=round(gap, 3)))
        if f.msgid == 0:
            if s.last_heartbeat is not None and 0 < t - s.last_heartbeat <= s.timeout:
                s.period = (1 - EMA) * s.period + EMA * (t - s.last_heartbeat) if s.heartbeats >= 2 \
                    else t - s.last_heartbeat
            s.heartbeats += 1
            s.last_heartbeat = t
        if t >= s.last_time:
            s.last_time, s.last_frame = t, f
        return out

    def finish(self) -> Iterable[Event]:
        out = []
        for me, s in self.senders.items():
            if self.end is not None and s.heartbeats >= 2 and self.end - s.last_time > s.timeout:
                silent = self.end - s.last_time
                out.append(at(s.last_frame, LINK, f"{addr(me)} falls silent for the last {silent:.1f} s of the "
                                                  "capture", what="lost", silent_s=round(silent, 3)))
        return out
