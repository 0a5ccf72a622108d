"""The flight's story: every event source over the frames of a capture, in one pass.

`EventLog(dialect).add(frame)` for every frame in capture order, then `finish()`: the events sorted by
the frame they are dated by (capture order; events of one frame in the order their sources made them).
Each payload is decoded once, for the sources that want it (every source sees every frame); frames whose
CRC is not good are left out, for every source (their content cannot be trusted). At most MAX_PER_KIND
events of each kind are kept: the rest are counted in `dropped`, so a capture full of STATUSTEXT cannot
crowd out the arming events or grow the log without bound.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

from mavscope.analysis.events.links import LinkHealth, Signing
from mavscope.analysis.events.model import KINDS, Event, EventSource
from mavscope.analysis.events.records import FileEvents, ParamEvents
from mavscope.analysis.events.traffic import Commands, Missions
from mavscope.analysis.events.vehicle import MissionProgress, StatusTexts, VehicleStates
from mavscope.analysis.selection import Selection
from mavscope.analysis.vehicles import Systems
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload

MAX_PER_KIND = 5000

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
    dropped: Counter[str] = field(default_factory=Counter)  # events left out per kind (over MAX_PER_KIND)

    def to_json(self, select: Selection | None = None) -> dict[str, object]:
        events = [e for e in self.events if select is None or select.any_record((e.frame,))]
        return {"events": [e.to_json() for e in events],
                "counts": {k: self.counts[k] for k in KINDS if self.counts[k]},
                "dropped": {k: self.dropped[k] for k in KINDS if self.dropped[k]}}


class EventLog:
    """Runs event sources over frames (see the module docstring)."""

    def __init__(self, dialect: Dialect, sources: Sequence[SourceFactory] | None = None) -> None:
        self.dialect = dialect
        self.systems = Systems(dialect)
        self.sources = [make(self.systems, dialect) for make in (SOURCES if sources is None else sources)]
        self.decode = frozenset().union(*(s.wants for s in self.sources)) | {"HEARTBEAT"}
        self.kept: list[tuple[int, int, Event]] = []  # (frame, order made, event)
        self.counts: Counter[str] = Counter()
        self.dropped: Counter[str] = Counter()

    def _keep(self, events: Iterable[Event]) -> None:
        for e in events:
            self.counts[e.kind] += 1
            if self.counts[e.kind] > MAX_PER_KIND:
                self.dropped[e.kind] += 1
            else:
                self.kept.append((e.frame, len(self.kept), e))

    def add(self, f: Frame) -> None:
        if f.crc_status is not CrcStatus.OK:
            return
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
        self.kept.sort(key=lambda k: (k[0], k[1]))
        return EventList([e for _, _, e in self.kept], self.counts, self.dropped)


def story(frames: Iterable[Frame], dialect: Dialect) -> EventList:
    """The events of `frames` (in capture order) in one call."""
    log = EventLog(dialect)
    for f in frames:
        log.add(f)
    return log.finish()
