"""The pure-Python batch source, the reference: the session (dissector and security stage), the expert,
audit, objects and params analyses and the column builders in one pass over a capture.

The pieces any source shares live here too: the capture summary (`CaptureSummary`), the analyses a
capture's findings come from (`Analyses`), and the findings and captures batches.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from datetime import datetime, timezone

import pyarrow as pa

from mavscope import __version__
from mavscope.analysis.audit_pass import AuditPass
from mavscope.analysis.command_log import CommandMatcher
from mavscope.analysis.expert import Expert
from mavscope.analysis.objects import ObjectTracker
from mavscope.analysis.params import ParamTracker
from mavscope.export.columns import AnomalyColumns, FrameColumns, MessageTables
from mavscope.export.options import ExportOptions, Progress, Warn, dialect_for
from mavscope.export.schema import FINDINGS, FRAMES, SCHEMA_VERSION, captures_schema, findings_schema
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.notes import CODES, Finding, Note, is_capture_damage, problem_line
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.session import open_session
from mavscope.rules import rule_set

PYTHON = "python"


def findings_batch(capture_id: str, found: list[tuple[str, Finding]]) -> pa.RecordBatch:
    n = len(found)
    return pa.RecordBatch.from_arrays([
        pa.array([capture_id] * n, pa.string()),
        pa.array([s for s, _ in found], pa.string()),
        pa.array([f.code for _, f in found], pa.string()),
        pa.array([f.severity.value for _, f in found], pa.string()),
        pa.array([CODES[f.code].group.value for _, f in found], pa.string()),
        pa.array([f.message for _, f in found], pa.string()),
        pa.array([list(f.frames) for _, f in found], pa.list_(pa.int64())),
        pa.array([f.rule for _, f in found], pa.string()),
    ], schema=findings_schema())


@dataclass
class CaptureSummary:
    frames: int = 0
    first: float | None = None
    last: float | None = None
    problems: int = 0  # what `read` reports on stderr: anomalies' notes, frames' notes of capture damage
    first_problem: str | None = None

    def problem(self, where: str, n: Note) -> None:
        self.problems += 1
        if self.first_problem is None:
            self.first_problem = problem_line(where, n)

    def damage(self, f: Frame) -> None:
        """The notes of damage to the file a frame carries, in capture order."""
        if f.notes:
            for n in f.notes:
                if is_capture_damage(n):
                    self.problem(f"frame {f.number}", n)

    def anomaly(self, item: Anomaly) -> None:
        for n in item.notes:
            self.problem(f"record {item.record}", n)

    def frame(self, f: Frame) -> None:
        """A frame in capture order: counted, its time and its notes of damage taken."""
        self.frames += 1
        self.damage(f)
        t = f.time
        if t is not None:
            if self.first is None:
                self.first = t
            self.last = t


class Analyses:
    """The analyses whose findings make the findings table: `stats`' expert detectors, `audit` (no
    wordlist: its one pass, `AuditPass`, whose `audit` part is `audit` here, with the shipped pack of detection
    rules, as `audit` runs it by default), `objects` and `params` with their default limits."""

    def __init__(self, dialect: Dialect) -> None:
        self.expert, self.audit_pass = Expert(dialect), AuditPass(dialect, rules=rule_set(dialect))
        self.audit = self.audit_pass.audit
        self.objects, self.params = ObjectTracker(), ParamTracker()
        self.objects.use_dialect(dialect)

    def anomaly(self, item: Anomaly) -> None:
        """What belongs to no frame, in capture order (the audit's IP fragment findings)."""
        self.audit_pass.anomaly(item)

    def add(self, f: Frame) -> None:
        """One frame, in capture order."""
        self.audit_pass.add(f, self.expert.add(f))  # the fields the expert decoded, decoded once
        self.objects.feed(f)
        self.took(self.objects)
        self.params.feed(f)

    @staticmethod
    def took(objects: ObjectTracker) -> None:
        if objects.finished_waiting:
            objects.take()  # the findings need no object's bytes: let them go

    def findings(self) -> list[tuple[str, Finding]]:
        """(source, finding) of every analysis, at the end of the capture (`audit`'s as the command gives
        them: with the expert's security findings, mavscope.analysis.audit_pass)."""
        expert = self.expert.findings()
        return ([("stats", f) for f in expert] + [("audit", f) for f in self.audit_pass.result(expert)[0]]
                + [("objects", f) for f in self.objects.finish().findings]
                + [("params", f) for f in self.params.finish().findings])


def pure_pass(path: str, options: ExportOptions, dialect: Dialect, take: Callable[[Frame], object]) -> None:
    """Every frame of the capture to `take`, one pass of the pure pipeline (the native source's fallback
    for an analysis it cannot serve on a capture)."""
    popts = replace(options.pipeline, display_filter=None)
    with open_session(path, popts, dialect=dialect, warn=lambda _m: None) as session:
        for item in session.items:
            if type(item) is not Anomaly:
                take(item)


def command_pass(path: str, options: ExportOptions, dialect: Dialect) -> CommandMatcher:
    """The audit's command matcher over a pure pass (where the native feed's commands could have reached
    its bound: native_commands.CommandKeys.may_give_up)."""
    audit = AuditPass(dialect)
    pure_pass(path, options, dialect, audit.command)
    return audit.matcher


def python_source(path: str, capture_id: str, options: ExportOptions, progress: Progress | None,
                  warn: Warn | None) -> Iterator[pa.RecordBatch]:
    """The pure-Python batch source: session, the analyses with findings, column builders, one pass."""
    popts = replace(options.pipeline, display_filter=None)  # an export holds every frame
    dialect = dialect_for(popts)
    rows = options.batch_rows
    want_frames = options.wants(FRAMES)
    want_findings = options.wants(FINDINGS)
    want_messages = options.wants_messages
    with open_session(path, popts, dialect=dialect, warn=warn or (lambda _m: None)) as session:
        name = session.name
        frames = FrameColumns(capture_id, name, rows)
        messages = MessageTables(capture_id, dialect, rows)
        anomalies = AnomalyColumns(capture_id, rows)
        analyses = Analyses(dialect)
        summary = CaptureSummary()
        reader = session.reader
        tick = 0
        for item in session.items:
            if type(item) is Anomaly:
                summary.anomaly(item)
                if want_findings:
                    analyses.anomaly(item)
                b = anomalies.add(item)
                if b is not None:
                    yield b
                continue
            summary.frame(item)
            if want_findings:
                analyses.add(item)
            if want_frames:
                b = frames.add(item)
                if b is not None:
                    yield b
            if want_messages:
                yield from messages.add(item)
            tick += 1
            if progress is not None and tick >= 4096:
                tick = 0
                progress(reader.position)
        b = frames.flush() if want_frames else None
        if b is not None:
            yield b
        yield from messages.flush()
        found = analyses.findings() if want_findings else []
        if want_findings:
            yield findings_batch(capture_id, found)
        b = anomalies.flush()
        if b is not None:
            yield b
        if progress is not None:
            progress(reader.position)
        yield captures_batch(capture_id, session.path, name, reader.size, reader.kind, summary, anomalies.count,
                             len(found) if want_findings else None, len(messages.counts), dialect, options, PYTHON)


def captures_batch(capture_id: str, path: str, name: str, size: int, kind: str, s: CaptureSummary, anomalies: int,
                   findings: int | None, types: int, dialect: Dialect, options: ExportOptions,
                   source: str) -> pa.RecordBatch:
    values: list[object] = [
        capture_id, name, os.path.basename(os.fsencode(path)).decode("utf-8", "backslashreplace"), size, kind,
        s.frames, anomalies, s.problems, s.first_problem, findings, types, s.first, s.last,
        options.pipeline.has_key_material,
        [os.path.basename(f) for f in dialect.files], source, __version__, SCHEMA_VERSION,
        datetime.fromtimestamp(time.time(), tz=timezone.utc),
    ]
    schema = captures_schema()
    return pa.RecordBatch.from_arrays([pa.array([v], schema.field(i).type) for i, v in enumerate(values)],
                                      schema=schema)
