"""The flight's story: every event source over the frames of a capture, in one pass.

`EventLog(dialect).add(frame)` for every frame in capture order, then `finish()`: the events sorted by
the frame they are dated by (capture order; events of one frame in the order their sources made them).
Each payload is decoded once, for the sources that want it (every source sees every frame); frames whose
CRC is not good are left out, for every source (their content cannot be trusted).

Bounded (docs/security.md, "Bounds"), so that a flood cannot choose what the list loses: of each kind and
sender the first FIRST_KEPT and the last LAST_KEPT events are listed (a flood of one kind from one sender
gives up its own middle); MAX_CHATTER STATUSTEXT and link events are listed in all, and MAX_EVENTS of
the other kinds (arming, modes, commands, missions...), so that a flood of one never pushes out the
other. Past those, an event of the least established sender goes (fewest frames, in powers of two), the
newest group of equals: a flood of made-up senders churns its own. Every event left out is counted per
kind (`dropped`) and said as a `capacity` finding (`EventList.capacity`, with what a source's own bound
gave up: a source may list those findings in a `capacity` attribute once finished).
"""

from __future__ import annotations

import heapq
from collections import Counter, deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

from mavscope.analysis.events.links import LinkHealth, Signing
from mavscope.analysis.events.model import KINDS, LINK, STATUSTEXT, Event, EventSource, addr
from mavscope.analysis.events.records import FileEvents, ParamEvents
from mavscope.analysis.events.traffic import Commands, Missions
from mavscope.analysis.events.vehicle import MissionProgress, StatusTexts, VehicleStates
from mavscope.analysis.selection import Selection
from mavscope.analysis.vehicles import Systems
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Addr, CrcStatus, Frame, decode_payload
from mavscope.notes import Finding, GivenUp

FIRST_KEPT = 2500  # the first events of each (kind, sender) listed...
LAST_KEPT = 2500  # ...and its last ones: those between are left out, counted and said
MAX_EVENTS = 40_000  # events of the kinds but chatter listed in all: past it the least established sender's go
MAX_CHATTER = 20_000  # events of CHATTER listed in all, alike
CHATTER = frozenset({STATUSTEXT, LINK})  # kinds with a bound of their own: no flood of them crowds out the others

# A source factory: (the shared HEARTBEAT registry, the dialect) -> an event source.
SourceFactory = Callable[[Systems, Dialect], EventSource]

SOURCES: list[SourceFactory] = [
    lambda systems, dialect: VehicleStates(systems, dialect),
    lambda systems, dialect: MissionProgress(),
    lambda systems, dialect: StatusTexts(dialect),
    lambda systems, dialect: Commands(systems, dialect),
    lambda systems, dialect: Missions(dialect),
    lambda systems, dialect: ParamEvents(),  # the parameter analysis's timeline (`mavscope params`)
    lambda systems, dialect: FileEvents(dialect),  # the object reconstruction's records (`mavscope objects`)
    lambda systems, dialect: Signing(),
    lambda systems, dialect: LinkHealth(),
]


@dataclass
class EventList:
    events: list[Event]
    counts: Counter[str] = field(default_factory=Counter)  # events made, per kind (kept or not)
    dropped: Counter[str] = field(default_factory=Counter)  # events left out per kind (the bounds above)
    # `capacity` findings: of the events left out, and of what a source's bound gave up (mission transfers)
    capacity: list[Finding] = field(default_factory=list)

    def to_json(self, select: Selection | None = None) -> dict[str, object]:
        events = [e for e in self.events if select is None or select.any_record((e.frame,))]
        return {"events": [e.to_json() for e in events],
                "counts": {k: self.counts[k] for k in KINDS if self.counts[k]},
                "dropped": {k: self.dropped[k] for k in KINDS if self.dropped[k]}}


Kept = tuple[int, int, Event]  # (frame, order made, event)


class _Group:
    """The events listed of one (kind, sender): its first ones, then a ring of its last ones, `cap` in all."""

    __slots__ = ("head", "tail", "cap", "serial")

    def __init__(self, serial: int) -> None:
        self.head: list[Kept] = []
        self.tail: deque[Kept] = deque()
        self.cap = FIRST_KEPT + LAST_KEPT
        self.serial = serial

    def put(self, k: Kept) -> Kept | None:
        """Keep `k`; the event this group then leaves out (its oldest of the last ones), if any."""
        if len(self.head) < min(FIRST_KEPT, self.cap):
            self.head.append(k)
            return None
        self.tail.append(k)
        return self.tail.popleft() if len(self.head) + len(self.tail) > self.cap else None

    def shed(self) -> Kept:
        """Give up one event for another group's (the oldest of the last ones, else the latest of the first)."""
        k = self.tail.popleft() if self.tail else self.head.pop()
        self.cap = len(self.head) + len(self.tail)
        return k


class _Listing:
    """The events kept under the bounds of the module docstring; `frames` counts each sender's frames. Two
    pools, chatter (1) and the other kinds (0), each with its count held and a heap of its groups by how
    established their sender is: (frames' bit length, -serial, key), lazily brought up to date."""

    def __init__(self) -> None:
        self.groups: dict[tuple[str, Addr], _Group] = {}
        self.heaps: tuple[list[tuple[int, int, tuple[str, Addr]]], ...] = ([], [])
        self.held = [0, 0]
        self.frames: Counter[Addr] = Counter()
        self.made = 0
        self.dropped: Counter[str] = Counter()
        self.given_up = GivenUp(f"events listed (of each kind and sender the first {FIRST_KEPT:,} and the last "
                                f"{LAST_KEPT:,}; {MAX_EVENTS:,} in all, {MAX_CHATTER:,} of STATUSTEXT and link "
                                "events)", "events")

    def _drop(self, k: Kept, why: str) -> None:
        e = k[2]
        self.dropped[e.kind] += 1
        self.given_up.add(f"a {e.kind} event of {addr(e.sender)} (frame {e.frame}) not listed: {why}", 1, e.frame)

    def keep(self, e: Event) -> None:
        key = (e.kind, e.sender)
        pool = int(e.kind in CHATTER)
        g = self.groups.get(key)
        if g is None:
            g = self.groups[key] = _Group(self.made)
            heapq.heappush(self.heaps[pool], (self.frames[e.sender].bit_length(), -g.serial, key))
        self.made += 1
        out = g.put((e.frame, self.made, e))
        if out is not None:
            self._drop(out, "between the first and the last listed of its kind and sender")
            return
        self.held[pool] += 1
        if self.held[pool] > (MAX_CHATTER if pool else MAX_EVENTS):
            self._shed(pool)

    def _shed(self, pool: int) -> None:
        heap = self.heaps[pool]
        while True:
            cls, serial, key = heap[0]
            g = self.groups.get(key)
            if g is None or g.serial != -serial:
                heapq.heappop(heap)
                continue
            now = self.frames[key[1]].bit_length()
            if now == cls:
                break
            heapq.heapreplace(heap, (now, serial, key))
        self._drop(g.shed(), "the bound is full; this sender is the least established")
        self.held[pool] -= 1
        if not g.cap:
            del self.groups[key]
            heapq.heappop(heap)
        if len(heap) > 4 * len(self.groups) + 4096:  # entries of groups gone
            heap[:] = [h for h in heap if (g := self.groups.get(h[2])) is not None and g.serial == -h[1]]
            heapq.heapify(heap)

    def kept(self) -> list[Kept]:
        out = [k for g in self.groups.values() for k in (*g.head, *g.tail)]
        out.sort(key=lambda k: (k[0], k[1]))
        return out


class EventLog:
    """Runs event sources over frames (see the module docstring)."""

    def __init__(self, dialect: Dialect, sources: Sequence[SourceFactory] | None = None) -> None:
        self.dialect = dialect
        self.systems = Systems(dialect)
        self.sources = [make(self.systems, dialect) for make in (SOURCES if sources is None else sources)]
        self.decode = frozenset().union(*(s.wants for s in self.sources)) | {"HEARTBEAT"}
        self.listing = _Listing()
        self.counts: Counter[str] = Counter()

    def _keep(self, events: Iterable[Event]) -> None:
        for e in events:
            self.counts[e.kind] += 1
            self.listing.keep(e)

    def add(self, f: Frame) -> None:
        if f.crc_status is not CrcStatus.OK:
            return
        self.listing.frames[(f.sysid, f.compid)] += 1
        md = f.msgdef
        fields = decode_payload(f) if md is not None and md.name in self.decode else None
        if fields is not None and f.msgid == 0:
            self.systems.see(f, fields)
        name = md.name if md is not None else ""
        for s in self.sources:
            self._keep(s.add(f, fields if name in s.wants else None))

    def finish(self) -> EventList:
        for s in self.sources:
            self._keep(s.finish())
        listing = self.listing
        said = [listing.given_up.finding(), *(f for s in self.sources for f in getattr(s, "capacity", ()))]
        return EventList([e for _, _, e in listing.kept()], self.counts, listing.dropped,
                         [f for f in said if f is not None])


def story(frames: Iterable[Frame], dialect: Dialect) -> EventList:
    """The events of `frames` (in capture order) in one call."""
    log = EventLog(dialect)
    for f in frames:
        log.add(f)
    return log.finish()
