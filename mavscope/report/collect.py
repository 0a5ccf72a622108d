"""One pass over a capture feeding every analysis the report shows, as the commands that show them feed them.

`collect(session, ...)` walks `Session.batches` once (the engine the session chose: the native walker's
windows where it reads the capture): each batch goes to `stats`' accumulator and the expert's batch
detectors (`mavscope stats --json`'s figures and findings, mavscope.commands.stats), and every frame of it,
in capture order, to `audit`'s pass (mavscope.analysis.audit_pass.AuditPass with the flight's story, as
mavscope.commands.audit builds it), whose findings with the expert's are `audit --json`'s. The story
(`events`) is the audit pass's own EventLog; its sources' trackers are the analyses of `mission`, `params`
and `objects`, whose results the report reads as the story leaves them (`_Kept`). The track (`track`) and
the plotted fields (`plot`) take the frames of the messages they read, which is all their `add` reads.
Nothing here computes what an analysis computes: it only feeds them and keeps what they give back.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mavscope.analysis import expert_batch
from mavscope.analysis.audit_pass import AuditPass
from mavscope.analysis.events import EventList, EventLog
from mavscope.analysis.events.records import ParamEvents
from mavscope.analysis.events.traffic import Missions
from mavscope.analysis.expert import Expert
from mavscope.analysis.mission import TRACKED_MESSAGES as MISSION_TRACKED
from mavscope.analysis.mission import MissionLog
from mavscope.analysis.params import ParamLog
from mavscope.analysis.series import Plotter
from mavscope.analysis.stats import Stats, StatsBuilder
from mavscope.analysis.track import SOURCES as TRACK_SOURCES
from mavscope.analysis.track import TrackBuilder, Tracks
from mavscope.analysis.vehicles import Systems
from mavscope.fields.registry import FieldRegistry
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.floats import f32_value
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding
from mavscope.pipeline.batch import VERDICTS, FrameBatch
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.session import Session
from mavscope.rules import RuleSet

# The plotted fields (`mavscope plot FILE EXPR...`'s expressions), with how the page shows them.
PLOTS: tuple[tuple[str, str, str, float], ...] = (  # (expression, title, unit shown, divisor to that unit)
    ("GLOBAL_POSITION_INT.relative_alt", "Altitude above home", "m", 1000.0),
    ("VFR_HUD.groundspeed", "Ground speed", "m/s", 1.0),
    ("SYS_STATUS.voltage_battery", "Battery voltage", "V", 1000.0),
    ("GPS_RAW_INT.fix_type", "GPS fix type", "", 1.0),
    ("GPS_RAW_INT.satellites_visible", "Satellites visible", "", 1.0),
)
PLOTTED = frozenset(expr.split(".", 1)[0] for expr, *_ in PLOTS)
TRACKED = MISSION_TRACKED | frozenset(TRACK_SOURCES)  # what TrackBuilder.add reads (it returns on any other)
FIRMWARE = "AUTOPILOT_VERSION"
MAX_VERDICT_CELLS = 1 << 16  # (second, verdict) counts kept: past it the seconds double in width


class VerdictSeries:
    """Frames per signature verdict per time slot (seconds from the first timed frame, the slots doubling
    in width past MAX_VERDICT_CELLS cells): counts taken from the batches' verdict columns."""

    def __init__(self) -> None:
        self.origin: float | None = None
        self.width = 1.0
        self.cells: Counter[tuple[int, int]] = Counter()

    def add(self, b: FrameBatch) -> None:
        timed = b.timed & np.isfinite(b.time)
        if not timed.any():
            return
        t = b.time[timed]
        if self.origin is None:
            self.origin = float(t[0])
        slot = np.floor(np.maximum(t - self.origin, 0.0) / self.width).astype(np.int64)
        key = slot * 16 + b.verdict[timed].astype(np.int64)
        values, counts = np.unique(key, return_counts=True)
        cells = self.cells
        for k, n in zip(values.tolist(), counts.tolist()):
            cells[(k >> 4, k & 15)] += n
        while len(cells) > MAX_VERDICT_CELLS:
            self.width *= 2
            merged: Counter[tuple[int, int]] = Counter()
            for (s, v), n in cells.items():
                merged[(s // 2, v)] += n
            self.cells = cells = merged

    def to_json(self) -> dict[str, object]:
        per: dict[str, list[list[float]]] = {}
        for (s, v), n in sorted(self.cells.items()):
            per.setdefault(VERDICTS[v], []).append([round(s * self.width, 9), n / self.width])
        return {"interval": self.width, "start": self.origin,
                "verdicts": {k: per[k] for k in sorted(per)}}


def float_fields(dialect: Dialect) -> frozenset[tuple[str, str]]:
    """The plotted fields that are float32 in the dialect."""
    out = set()
    for expr, *_ in PLOTS:
        message, key = expr.split(".", 1)
        md = dialect.by_name.get(message)
        fd = md.field(key) if md is not None else None
        if fd is not None and fd.type == "float":
            out.add((message, key))
    return frozenset(out)


def plot(plotter: Plotter, b: FrameBatch, floats: frozenset[tuple[str, str]]) -> None:
    """`plotter.add` for every frame of the batch, for the report's fields (PLOTS: payload fields of one
    message each): the frames until the x axis has its origin go to `add` itself; after that only the
    plotted messages' frames can add a value, and their values are read from the batch's payloads, decoded
    per message at once (FrameBatch.decoded, before the rows have Frames), rather than by a getter per
    frame; each goes to its Series as `add` gives it (x from the axis' origin: the frame's capture time, or
    its record number in a capture without times; NaN and the infinities counted apart)."""
    start = 0
    if plotter.origin is None:
        for start in range(1, b.n + 1):
            plotter.add(b.frame(start - 1))
            if plotter.origin is not None:
                break
        else:
            return
    origin, by_time = plotter.origin, plotter.x_label == "s"
    assert origin is not None
    times, timed, records = b.time.tolist(), b.timed.tolist(), b.record.tolist()
    for message, plots in _by_message(plotter, floats):
        rows = [r for r in np.flatnonzero(b.of_messages((message,))).tolist() if r >= start]
        for row, fields in zip(rows, b.decoded(rows, frozenset((message,)))):
            if fields is None:  # (a bad CRC, a payload it cannot decode: the getters decide, as for `plot`)
                plotter.add(b.frame(row))
                continue
            if by_time:
                t = times[row]
                if not timed[row] or not math.isfinite(t):
                    continue
                x = t - origin
            else:
                x = float(records[row]) - origin
            for key, series, is_float in plots:
                v = fields.get(key)
                if is_float and type(v) is float:
                    v = f32_value(v)  # (as the getter gives a float32 field: its shortest decimal)
                if isinstance(v, bool) or not isinstance(v, (int, float)):
                    continue
                if math.isfinite(v):
                    series.add(x, float(v))
                else:
                    series.not_finite += 1


def _by_message(plotter: Plotter, floats: frozenset[tuple[str, str]]) -> list[tuple[str, list[tuple[str, Any, bool]]]]:
    """The plotted fields by message: (message, [(field, its Series, float32)])."""
    out: dict[str, list[tuple[str, Any, bool]]] = {}
    for (expr, *_), series in zip(PLOTS, plotter.series):
        message, key = expr.split(".", 1)
        out.setdefault(message, []).append((key, series, (message, key) in floats))
    return list(out.items())


class _Kept:
    """A tracker's `finish()` made to keep its result: the story finishes its sources' trackers (mission,
    params), and the report reads what they gave it rather than finishing them twice."""

    def __init__(self, tracker: Any) -> None:
        self.result: Any = None
        finish: Callable[[], Any] = tracker.finish

        def kept() -> Any:
            if self.result is None:
                self.result = finish()
            return self.result

        tracker.finish = kept


@dataclass
class Collected:
    """What the analyses gave for one capture."""

    frames: int
    stats: Stats
    findings: list[Finding]
    story: EventList
    systems: Systems
    missions: MissionLog | None
    params: ParamLog | None
    tracks: Tracks
    plotter: Plotter
    verdicts: VerdictSeries
    firmware: dict[tuple[int, int], dict[str, object]] = field(default_factory=dict)


def _firmware(fields: dict[str, object]) -> dict[str, object]:
    """AUTOPILOT_VERSION's version words as sent (flight_sw_version: major.minor.patch and the release type
    in its four bytes, MAVLink's definition), the git hash prefix as hex."""
    out: dict[str, object] = {}
    for key in ("flight_sw_version", "middleware_sw_version", "os_sw_version", "board_version"):
        v = fields.get(key)
        if isinstance(v, int):
            out[key] = v
    v = out.get("flight_sw_version")
    if isinstance(v, int):
        out["flight"] = f"{v >> 24 & 255}.{v >> 16 & 255}.{v >> 8 & 255} (type {v & 255})"
    custom = fields.get("flight_custom_version")
    if isinstance(custom, (bytes, list)):
        raw = bytes(custom)
        # the first bytes of the git hash: ArduPilot sends them as ASCII hex digits, others as bytes
        text = raw.rstrip(b"\0")
        out["git"] = text.decode() if text and all(c in b"0123456789abcdef" for c in text) else raw.hex()
    uid = fields.get("uid")
    if isinstance(uid, int):
        out["uid"] = uid
    return out


def collect(session: Session, report: Callable[[Frame | Anomaly], object], rules: RuleSet | None = None) -> Collected:
    """The analyses of the session's capture, in one pass (see the module docstring); `report` gets each
    anomaly and frame with notes as `Session.batches` gives them (the command's stderr lines); `rules`: the
    detection rules `audit` runs with the same options (mavscope.rules.rule_set)."""
    dialect = session.dialect
    audit, expert, builder = AuditPass(dialect, story=True, rules=rules), Expert(dialect), StatsBuilder()
    story = audit.story if audit.story is not None else EventLog(dialect)
    kept_story = _Kept(story)  # (audit.result finishes the story: the events are what it finished with)
    kept_missions = kept_params = None
    track = TrackBuilder(dialect)
    for source in story.sources:
        if isinstance(source, Missions):
            kept_missions = _Kept(source.tracker)
            # the track's mission tracker would be fed the very frames the story's is (TRACKED_MESSAGES with a
            # good CRC, in capture order): the track takes the story's, and only its positions are fed to it
            track.missions = source.tracker
        elif isinstance(source, ParamEvents):
            kept_params = _Kept(source.tracker)
    positions = frozenset(TRACK_SOURCES) if kept_missions is not None else TRACKED
    plotter = Plotter(FieldRegistry(dialect), [expr for expr, *_ in PLOTS])
    verdicts = VerdictSeries()
    floats = float_fields(dialect)
    firmware: dict[tuple[int, int], dict[str, object]] = {}

    def seen(item: Frame | Anomaly) -> None:
        if type(item) is Anomaly:
            audit.anomaly(item)  # (audit's Pass gives the audit every anomaly)
        report(item)

    add, own_story = audit.add, audit.story is None
    for b in session.batches(seen):
        expert_batch.feed(expert, b, builder.add_batch(b))
        verdicts.add(b)
        plot(plotter, b, floats)  # (before the rows have Frames: their payloads decoded per message at once)
        frames = b.frames(range(b.n))
        for f in frames:
            add(f)
        if own_story:
            for f in frames:
                story.add(f)
        for row in np.flatnonzero(b.of_messages(positions)).tolist():
            track.add(frames[row])
        rows = np.flatnonzero(b.of_messages((FIRMWARE,))).tolist()
        for row, fields in zip(rows, b.decoded(rows, frozenset((FIRMWARE,)))):
            if fields is not None:
                firmware[(int(b.sysid[row]), int(b.compid[row]))] = _firmware(fields)
    stats = builder.result()
    stats.logged_in_part = expert.logged_in_part()
    findings, _ = audit.result(expert.findings())
    events: EventList = story.finish() if kept_story.result is None else kept_story.result
    return Collected(session.frame_count, stats, findings, events, story.systems,
                     kept_missions.result if kept_missions is not None else None,
                     kept_params.result if kept_params is not None else None,
                     track.result(), plotter, verdicts, firmware)


def finite(x: float | None) -> float | None:
    """A float for JSON: None for NaN and the infinities."""
    return x if x is not None and math.isfinite(x) else None
