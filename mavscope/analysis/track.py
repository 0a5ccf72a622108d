"""The vehicles' tracks: timestamped positions per system, with the mission, fence and rally points beside
them (for `mavscope track`, exported as GeoJSON, KML or GPX by `mavscope.output.geo`).

Positions come from GLOBAL_POSITION_INT (the autopilot's estimate) and, for a sender that has none, from
GPS_RAW_INT with at least a 2D fix. Positions within NULL_ISLAND degrees of 0, 0 are "no position yet"
(ArduPilot reports offsets from 0, 0 until its EKF origin is set). Each track keeps at most MAX_POINTS
points: past that it keeps every second point and from then on takes every second position (and so on,
doubling), so a track of any length costs bounded memory and stays evenly spread over the flight.
The mission, fence and rally points are those `mavscope mission --plan` exports (`mission.to_plan`): what the
vehicle holds at the end of the capture. When it holds no mission any more (an accepted empty upload or
MISSION_CLEAR_ALL), the one it held before is kept beside the track as its history (`Tracks.history`),
marked with the time it was cleared.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from mavscope.analysis.gnss import NULL_ISLAND
from mavscope.analysis.mission import MissionTracker, PlanExport, to_plan
from mavscope.analysis.mission.reconstruct import TRACKED_MESSAGES
from mavscope.analysis.vehicles import MAX_SENDERS
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, decode_payload

MAX_POINTS = 20_000
SOURCES = ("GLOBAL_POSITION_INT", "GPS_RAW_INT")
GPS_FIX_TYPE_2D = 2


@dataclass(frozen=True, slots=True)
class Point:
    time: float | None  # capture time
    lat: float  # degrees
    lon: float
    alt: float  # metres above mean sea level
    record: int


@dataclass
class Track:
    sysid: int
    compid: int
    source: str  # the message the positions come from
    points: list[Point] = field(default_factory=list)
    seen: int = 0  # positions in the capture (points holds every `stride`-th)
    stride: int = 1

    def add(self, p: Point) -> None:
        self.seen += 1
        if (self.seen - 1) % self.stride:
            return
        self.points.append(p)
        if len(self.points) > MAX_POINTS:
            self.points = self.points[::2]
            self.stride *= 2


@dataclass
class Tracks:
    tracks: list[Track]
    plan: PlanExport | None  # the mission, fence and rally points (None: no mission item in the capture)
    # the mission the vehicle held before it was cleared (None: it was not, or held none before)
    history: PlanExport | None = None
    history_until: float | None = None  # when it was cleared (capture time)


def _point(f: Frame, fields: dict[str, object]) -> Point | None:
    lat, lon, alt = fields.get("lat"), fields.get("lon"), fields.get("alt")
    if not isinstance(lat, int) or not isinstance(lon, int) or not isinstance(alt, int):
        return None
    la, lo = lat / 1e7, lon / 1e7
    if not (-90 <= la <= 90 and -180 <= lo <= 180) or (abs(la) < NULL_ISLAND and abs(lo) < NULL_ISLAND):
        return None
    return Point(f.time, la, lo, alt / 1000, f.record)


class TrackBuilder:
    """`add(frame)` for every frame in capture order, then `result()`."""

    def __init__(self, dialect: Dialect) -> None:
        self.dialect = dialect
        self.tracks: dict[tuple[int, int, str], Track] = {}
        self.missions = MissionTracker(dialect)

    def add(self, f: Frame) -> None:
        md = f.msgdef
        if md is None or f.crc_status is not CrcStatus.OK:
            return
        name = md.name
        if name in TRACKED_MESSAGES:
            self.missions.feed(f)
            return
        if name not in SOURCES:
            return
        fields = decode_payload(f)
        if fields is None:
            return
        if name == "GPS_RAW_INT":
            fix = fields.get("fix_type")
            if not isinstance(fix, int) or fix < GPS_FIX_TYPE_2D:
                return
        p = _point(f, fields)
        if p is None:
            return
        key = (f.sysid, f.compid, name)
        t = self.tracks.get(key)
        if t is None:
            if len(self.tracks) >= MAX_SENDERS * len(SOURCES):
                return  # (unreachable: every (system, component) pair has a track of each source message)
            t = self.tracks[key] = Track(f.sysid, f.compid, name)
        t.add(p)

    def result(self) -> Tracks:
        fused = {(s, c) for s, c, name in self.tracks if name == "GLOBAL_POSITION_INT"}
        tracks = [t for (s, c, name), t in sorted(self.tracks.items())
                  if name == "GLOBAL_POSITION_INT" or (s, c) not in fused]
        log = self.missions.finish()
        plan = to_plan(log, self.dialect)
        cleared = plan.cleared.get("mission") if plan is not None else None
        if cleared is None or not cleared["history"]:
            return Tracks(tracks, plan)
        return Tracks(tracks, plan, to_plan(log, self.dialect, cleared["history"][-1] - 1), cleared["at"])


def tracks(frames: Iterable[Frame], dialect: Dialect) -> Tracks:
    b = TrackBuilder(dialect)
    for f in frames:
        b.add(f)
    return b.result()
