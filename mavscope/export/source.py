"""`record_batches(path, options)`: one capture as Arrow record batches of every dataset table.

This is the one function every engine runs per capture: the local exporter, its worker processes
(`-j N`), a Dask task, or a Spark `mapInArrow` (docs/dataset.md). Each batch says which table it
belongs to in its schema metadata (`table_of(batch)`); `ExportOptions.tables` keeps only some tables
(Spark wants one schema per output).

Where batches come from is a *batch source*, looked up by name in `SOURCES`: the pure-Python source
here runs the session (dissector and security stage), the expert, audit, objects and params analyses and
the column builders in one pass. A faster source (the native decoder, when it lands) registers itself with
`register_source(name, source)` and must yield the same tables with the same schemas and rows; the
test suite runs its contract over every registered source.
"""

from __future__ import annotations

import hashlib
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from functools import lru_cache

import pyarrow as pa

from mavscope import __version__
from mavscope.analysis.expert import Expert
from mavscope.analysis.objects import ObjectTracker
from mavscope.analysis.params import ParamTracker
from mavscope.capture.reader import open_file, pread
from mavscope.errors import CaptureError, UsageError
from mavscope.export.columns import DEFAULT_ROWS, AnomalyColumns, FrameColumns, MessageTables
from mavscope.export.schema import (
    CAPTURES,
    FINDINGS,
    FRAMES,
    MESSAGE_PREFIX,
    SCHEMA_VERSION,
    captures_schema,
    findings_schema,
    table_of,
)
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.notes import CODES, Finding, Note, is_capture_damage, problem_line
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from mavscope.security.audit import Audit

HASH_CHUNK = 1 << 20
Progress = Callable[[int], object]  # called with the capture's file offset reached so far
Warn = Callable[[str], object]


@dataclass(frozen=True, slots=True)
class ExportOptions:
    """What an export runs: the pipeline's options (dialects, key material; no display filter), the
    rows per record batch, the tables wanted (None: all) and the batch source."""

    pipeline: PipelineOptions = field(default_factory=PipelineOptions)
    batch_rows: int = DEFAULT_ROWS
    tables: frozenset[str] | None = None  # {"frames"}, {"msg=HEARTBEAT"}...; "msg=*" for every message table
    source: str = "python"
    capture_id: str | None = None  # the capture's SHA-256 when the caller has it already

    def wants(self, table: str) -> bool:
        t = self.tables
        return t is None or table in t or (table.startswith(MESSAGE_PREFIX) and "msg=*" in t)

    @property
    def wants_messages(self) -> bool:
        t = self.tables
        return t is None or any(x.startswith(MESSAGE_PREFIX) for x in t)


def content_id(path: str | os.PathLike[str]) -> str:
    """The capture id: SHA-256 of the file's bytes, in hex (CaptureError as `read` gives it)."""
    h = hashlib.sha256()
    spath, f, _ = open_file(path)
    try:
        offset = 0
        while chunk := pread(f, HASH_CHUNK, offset):
            h.update(chunk)
            offset += len(chunk)
    except OSError as e:
        raise CaptureError(f"cannot read: {e.strerror or e}", path=spath) from None
    finally:
        f.close()
    return h.hexdigest()


_dialect_lock = threading.Lock()  # pymavlink's parser and its stdout redirection are not thread-safe


@lru_cache(maxsize=8)
def _dialect(files: tuple[str, ...]) -> Dialect:
    return load_dialect(files)


def dialect_for(options: PipelineOptions) -> Dialect:
    """The dialect of `options`, loaded once per process (Dask workers run many captures each)."""
    with _dialect_lock:
        return _dialect(tuple(options.dialects))


BatchSource = Callable[[str, str, ExportOptions, Progress | None, Warn | None], Iterator[pa.RecordBatch]]
SOURCES: dict[str, BatchSource] = {}


def register_source(name: str, source: BatchSource) -> None:
    """Make a batch source available as `ExportOptions(source=name)`."""
    SOURCES[name] = source


def record_batches(path: str | os.PathLike[str], options: ExportOptions | None = None, *,
                   progress: Progress | None = None, warn: Warn | None = None) -> Iterator[pa.RecordBatch]:
    """Every table of the capture at `path` as record batches (each with a `capture_id` column, and
    its table in the schema metadata: `mavscope.export.table_of(batch)`), in bounded memory.

    Frames come in capture order, message tables as their rows fill a batch, then findings,
    anomalies not yet given, and last one `captures` row. CaptureError, UsageError and FilterError
    as `mavscope read` raises them."""
    options = options or ExportOptions()
    if options.batch_rows < 1:
        raise UsageError(f"export: batch_rows must be at least 1, not {options.batch_rows}")
    source = SOURCES.get(options.source)
    if source is None:
        raise UsageError(f"export: no batch source {options.source!r} (available: {', '.join(sorted(SOURCES))})")
    spath = os.fspath(path) if not isinstance(path, bytes) else os.fsdecode(path)
    cid = options.capture_id or content_id(spath)
    for batch in source(spath, cid, options, progress, warn):
        if options.wants(table_of(batch)):
            yield batch


def _findings_batch(capture_id: str, found: list[tuple[str, Finding]]) -> pa.RecordBatch:
    n = len(found)
    return pa.RecordBatch.from_arrays([
        pa.array([capture_id] * n, pa.string()),
        pa.array([s for s, _ in found], pa.string()),
        pa.array([f.code for _, f in found], pa.string()),
        pa.array([f.severity.value for _, f in found], pa.string()),
        pa.array([CODES[f.code].group.value for _, f in found], pa.string()),
        pa.array([f.message for _, f in found], pa.string()),
        pa.array([list(f.frames) for _, f in found], pa.list_(pa.int64())),
    ], schema=findings_schema())


@dataclass
class _Summary:
    frames: int = 0
    first: float | None = None
    last: float | None = None
    problems: int = 0  # what `read` reports on stderr: anomalies' notes, frames' notes of capture damage
    first_problem: str | None = None

    def problem(self, where: str, n: Note) -> None:
        self.problems += 1
        if self.first_problem is None:
            self.first_problem = problem_line(where, n)


def python_source(path: str, capture_id: str, options: ExportOptions, progress: Progress | None,
                  warn: Warn | None) -> Iterator[pa.RecordBatch]:
    """The pure-Python batch source: session, the analyses with findings, column builders, one pass."""
    popts = replace(options.pipeline, display_filter=None)  # an export holds every frame
    dialect = dialect_for(popts)
    rows = options.batch_rows
    want_frames = options.wants(FRAMES)
    want_findings = options.wants(FINDINGS) or options.wants(CAPTURES)
    want_messages = options.wants_messages
    with open_session(path, popts, dialect=dialect, warn=warn or (lambda _m: None)) as session:
        name = session.name
        frames = FrameColumns(capture_id, name, rows)
        messages = MessageTables(capture_id, dialect, rows)
        anomalies = AnomalyColumns(capture_id, rows)
        expert, audit, objects, params = Expert(dialect), Audit(), ObjectTracker(), ParamTracker()
        objects.use_dialect(dialect)
        summary = _Summary()
        reader = session.reader
        tick = 0
        for item in session.items:
            if type(item) is Anomaly:
                for n in item.notes:
                    summary.problem(f"record {item.record}", n)
                b = anomalies.add(item)
                if b is not None:
                    yield b
                continue
            summary.frames += 1
            if item.notes:
                for n in item.notes:
                    if is_capture_damage(n):
                        summary.problem(f"frame {item.number}", n)
            t = item.time
            if t is not None:
                if summary.first is None:
                    summary.first = t
                summary.last = t
            if want_findings:
                expert.add(item)
                audit.add(item)
                objects.feed(item)
                if objects.finished_waiting:
                    objects.take()  # the findings need no object's bytes: let them go
                params.feed(item)
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
        found: list[tuple[str, Finding]] = []
        if want_findings:
            found = ([("stats", f) for f in expert.findings()] + [("audit", f) for f in audit.result()[0]]
                     + [("objects", f) for f in objects.finish().findings]
                     + [("params", f) for f in params.finish().findings])
            yield _findings_batch(capture_id, found)
        b = anomalies.flush()
        if b is not None:
            yield b
        if progress is not None:
            progress(reader.position)
        yield _captures_batch(capture_id, session.path, name, reader.size, reader.kind, summary, anomalies.count,
                              len(found), len(messages.counts), dialect, options)


def _captures_batch(capture_id: str, path: str, name: str, size: int, kind: str, s: _Summary, anomalies: int,
                    findings: int, types: int, dialect: Dialect, options: ExportOptions) -> pa.RecordBatch:
    values: list[object] = [
        capture_id, name, os.path.basename(os.fsencode(path)).decode("utf-8", "backslashreplace"), size, kind,
        s.frames, anomalies, s.problems, s.first_problem, findings, types, s.first, s.last,
        options.pipeline.has_key_material,
        [os.path.basename(f) for f in dialect.files], options.source, __version__, SCHEMA_VERSION,
        datetime.fromtimestamp(time.time(), tz=timezone.utc),
    ]
    schema = captures_schema()
    return pa.RecordBatch.from_arrays([pa.array([v], schema.field(i).type) for i, v in enumerate(values)],
                                      schema=schema)


register_source("python", python_source)
