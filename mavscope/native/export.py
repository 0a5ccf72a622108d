"""The native batch source: the C extension walks the capture and fills column buffers in bulk; Python
wraps them into Arrow batches and hands the records C does not take to the pure path's pipeline.

The C walker (src/mavscope_native, column mode: columns.h) takes the records whose frames are all clean,
exactly those `read -T jsonl`'s native walk writes (docs/native.md), and fills per frame the frames
table's fixed-width columns, its payload and wire bytes, and per message the payloads zero-extended to
the message's length. Every other record is handed back, in capture order, to `Dissector.feed` and the
security stage, as the native `read` does; the frames they give go through the pure path's column
builders (columns.py) and are merged with the native rows in capture order. Frames are taken in windows
of at most WINDOW_FRAMES native frames (and as many handed-back ones): per window the frames table's rows
(native_columns.frames_batch, columns.frame_batch), the message tables' (native_columns.message_batch,
columns.MessageTables), and the analyses of the findings table (native_findings.NativeFeed). The tables,
schemas and rows are the pure source's (tests/export/test_sources.py); batches hold `batch_rows` rows
(the frames table exactly, message tables at most), their boundaries may differ from the pure source's.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pyarrow as pa

from mavscope.analysis import expert_batch
from mavscope.analysis.expert import Expert
from mavscope.capture.detect import open_capture
from mavscope.endpoint import Endpoint
from mavscope.export.columns import AnomalyColumns, MessageTables, frame_batch
from mavscope.export.findings_feed import NativeFeed, window_rows
from mavscope.export.options import ExportOptions, Progress, Warn, dialect_for
from mavscope.export.pure import (
    Analyses,
    CaptureSummary,
    captures_batch,
    command_pass,
    findings_batch,
    python_source,
)
from mavscope.export.schema import FINDINGS, FRAMES, frames_schema
from mavscope.mavlink.dialect import Dialect, MessageDef
from mavscope.mavlink.frame import Frame
from mavscope.native.chunk import Chunk
from mavscope.native.columns import Names, frames_batch, message_batch, message_plan
from mavscope.native.core import _native
from mavscope.native.tables import table_for
from mavscope.native.windows import DONE, FINISH, column_steps, column_walker
from mavscope.pipeline.batch import FrameBatch, Tables
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.pipeline.session import make_security_stage
from mavscope.security.stage import SecurityStage

NATIVE = "native"  # the source's name (export --source; `auto` runs it where core.available())
WINDOW_FRAMES = 65_536  # native frames per window

_tables: dict[int, tuple[Dialect, _native.Table, list[MessageDef], pa.Array]] = {}  # id(dialect) -> compiled


def _compiled(dialect: Dialect) -> tuple[_native.Table, list[MessageDef], pa.Array]:
    """The dialect's `_native.Table`, its messages in table order and their names (once per Dialect)."""
    got = _tables.get(id(dialect))
    if got is None or got[0] is not dialect:
        assert _native is not None
        if len(_tables) >= 8:  # as many as export.options keeps dialects
            _tables.clear()
        messages = sorted(dialect.messages.values(), key=lambda m: m.id)  # build_table's order
        got = _tables[id(dialect)] = (dialect, table_for(dialect), messages,
                                      pa.array([m.name for m in messages], pa.string()))
    return got[1], got[2], got[3]


class _Pending:
    """Batches waiting to be given: frames in `rows`-row batches, message tables per message (at most
    `rows` rows a batch, at most 4 x `rows` rows held over all of them: the largest goes first)."""

    def __init__(self, rows: int) -> None:
        self.rows = rows
        self.frames: list[pa.RecordBatch] = []
        self.frames_held = 0
        self.messages: dict[int, list[pa.RecordBatch]] = {}
        self.counts: dict[int, int] = {}

    def add_frames(self, batch: pa.RecordBatch) -> Iterator[pa.RecordBatch]:
        self.frames.append(batch)
        self.frames_held += batch.num_rows
        while self.frames_held >= self.rows:
            yield self._cut_frames(self.rows)

    def _cut_frames(self, k: int) -> pa.RecordBatch:
        first = self.frames[0]
        if first.num_rows >= k:  # a window of `k` rows or more: its rows as they are (a slice copies nothing)
            self.frames[0:1] = [first.slice(k)] if first.num_rows > k else []
            self.frames_held -= k
            return first.slice(0, k) if first.num_rows > k else first
        table = pa.Table.from_batches(self.frames, schema=self.frames[0].schema)
        head = table.slice(0, k).combine_chunks()
        self.frames = table.slice(k).to_batches()
        self.frames_held -= k
        return head.to_batches()[0]

    def add_message(self, msgid: int, batch: pa.RecordBatch) -> Iterator[pa.RecordBatch]:
        self.messages.setdefault(msgid, []).append(batch)
        self.counts[msgid] = self.counts.get(msgid, 0) + batch.num_rows
        while self.counts.get(msgid, 0) >= self.rows:
            yield self._cut_message(msgid, self.rows)
        while sum(self.counts.values()) > 4 * self.rows:
            largest = max(self.counts, key=lambda k: self.counts[k])
            yield self._cut_message(largest, self.counts[largest])

    def _cut_message(self, msgid: int, k: int) -> pa.RecordBatch:
        parts = self.messages[msgid]
        first = parts[0]
        if first.num_rows >= k:  # as _cut_frames: the first part's rows as they are (most cuts; no copy)
            head = first.slice(0, k) if first.num_rows > k else first
            rest = ([first.slice(k)] if first.num_rows > k else []) + parts[1:]
        else:
            table = pa.Table.from_batches(parts, schema=first.schema)
            head = table.slice(0, k).combine_chunks().to_batches()[0]
            rest = table.slice(k).to_batches()
        self.counts[msgid] -= k
        if rest:
            self.messages[msgid] = rest
        else:
            del self.messages[msgid], self.counts[msgid]
        return head

    def flush(self) -> Iterator[pa.RecordBatch]:
        if self.frames_held:
            yield self._cut_frames(self.frames_held)
        for msgid in list(self.messages):
            yield self._cut_message(msgid, self.counts[msgid])


def _merged(native: pa.RecordBatch | None, native_rows: np.ndarray, py: pa.RecordBatch | None,
            py_rows: np.ndarray) -> pa.RecordBatch:
    """The rows of both batches (one schema) in the order of their window rows."""
    if py is None:
        assert native is not None
        return native
    if native is None:
        return py
    order = np.argsort(np.concatenate([native_rows, py_rows]), kind="stable")
    table = pa.Table.from_batches([native, py]).take(pa.array(order))
    return table.combine_chunks().to_batches()[0]


class _Export:
    """One capture through the native source."""

    def __init__(self, path: str, kind: str, capture_id: str, options: ExportOptions, dialect: Dialect,
                 stage: SecurityStage) -> None:
        self.path, self.kind, self.capture_id, self.options = path, kind, capture_id, options
        self.dialect, self.stage = dialect, stage
        self.size = 0
        self.name = os.fsencode(path).decode("utf-8", "backslashreplace")
        self.table, self.messages, names = _compiled(dialect)
        self.want_frames = options.wants(FRAMES)
        self.want_messages = options.wants_messages
        self.want_findings = options.wants(FINDINGS)
        self.dissector = Dissector(dialect, self.stage.material.wifi)
        self.summary = CaptureSummary()
        self.anomalies = AnomalyColumns(capture_id, options.batch_rows)
        self.pending = _Pending(options.batch_rows)
        self.analyses = Analyses(dialect)
        self.feed = NativeFeed(self.analyses, self.messages)
        # the expert's detectors, fed each window as a FrameBatch (what `stats` computes them from)
        self.expert = Expert(dialect)
        self.tables = Tables()
        self.ends: list[Endpoint] = []
        self.names = Names(pa.array([], pa.string()), names)
        self.types: set[str] = set()  # messages with rows
        self.py: list[Frame] = []
        self.pos: list[int] = []  # native frames of the window before each of `py`
        self.py_anomalies: list[tuple[int, Anomaly]] = []  # the window's anomalies, each after so many of `py`
        self.py_messages = MessageTables(capture_id, dialect, 1 << 62)
        self.py_message_rows: dict[int, list[int]] = {}  # msgid -> the index in `py` of each row

    def python(self, items: Iterable[Frame | Anomaly], at: int) -> Iterator[pa.RecordBatch]:
        """Items of the Python pipeline, after `at` native frames of the window."""
        for item in self.stage.run(items):
            if type(item) is Anomaly:
                self.summary.anomaly(item)
                self.py_anomalies.append((len(self.py), item))  # to the audit in order with the frames
                b = self.anomalies.add(item)
                if b is not None:
                    yield b
                continue
            self.summary.damage(item)
            self.pos.append(at)
            self.py.append(item)
            if self.want_messages:
                held = self.py_messages.held
                for _ in self.py_messages.add(item):
                    raise AssertionError("MessageTables gave a batch of 2**62 rows")
                if self.py_messages.held > held:
                    self.py_message_rows.setdefault(item.msgid, []).append(len(self.py) - 1)

    def window(self, taken: tuple[int, bool, list[tuple[bytes, int]], list[Any], list[tuple[int, Any, Any, int]]],
               ) -> Iterator[pa.RecordBatch]:
        n, reset, new_ends, columns, parts = taken
        assert _native is not None
        if reset:
            self.ends.clear()
        if new_ends or reset:
            self.ends += [Endpoint.from_packed(a, port) for a, port in new_ends]
            self.names = Names(pa.array([e.text for e in self.ends], pa.string()), self.names.messages)
        c = Chunk(n, columns, _native.COLUMN_NAMES)
        py, pos = self.py, self.pos
        gn, gp = window_rows(n, pos)
        if self.want_frames and (n or py):
            native = frames_batch(c, self.names, self.capture_id, self.name) if n else None
            pyb = frame_batch(self.capture_id, self.name, py, frames_schema()) if py else None
            yield from self.pending.add_frames(_merged(native, gn, pyb, gp))
        if self.want_messages:
            yield from self._messages(c, parts, gn, gp)
        if self.want_findings:
            expert_batch.feed(self.expert, FrameBatch.of_window(c, py, pos, self.ends, self.messages, self.tables,
                                                                reset))
            self.feed.window(c, py, pos, self.ends, parts, self.py_anomalies)
        self._times(c, gn, gp)
        self.py, self.pos, self.py_anomalies = [], [], []

    def _messages(self, c: Chunk, parts: list[tuple[int, Any, Any, int]], gn: np.ndarray,
                  gp: np.ndarray) -> Iterator[pa.RecordBatch]:
        native: dict[int, tuple[pa.RecordBatch, np.ndarray]] = {}
        for position, rows, frames, count in parts:
            md = self.messages[position]
            at = np.frombuffer(frames, np.uint32, count=count)
            native[md.id] = (message_batch(message_plan(md, self.dialect), rows, at, c, self.capture_id), gn[at])
            self.types.add(md.name)
        python: dict[int, pa.RecordBatch] = {}
        for b in self.py_messages.flush():
            python[int((b.schema.metadata or {})[b"mavscope.msgid"])] = b
        self.types.update(self.py_messages.counts)
        for msgid in list(native) + [k for k in python if k not in native]:
            nb, nrows = native.get(msgid, (None, np.empty(0, np.int64)))
            pb = python.get(msgid)
            prows = gp[self.py_message_rows.get(msgid, [])]
            yield from self.pending.add_message(msgid, _merged(nb, nrows, pb, prows))
        self.py_messages = MessageTables(self.capture_id, self.dialect, 1 << 62)
        self.py_message_rows = {}

    def _times(self, c: Chunk, gn: np.ndarray, gp: np.ndarray) -> None:
        """Frames counted, the first and last time in capture order."""
        s = self.summary
        s.frames += c.n + len(self.py)
        timed = [(int(r), f.time) for r, f in zip(gp.tolist(), self.py) if f.time is not None]
        if c.n and c.time_ok.any():
            ok = np.flatnonzero(c.time_ok)
            timed += [(int(gn[ok[0]]), float(c.time[ok[0]])), (int(gn[ok[-1]]), float(c.time[ok[-1]]))]
        if timed:
            timed.sort()
            if s.first is None:
                s.first = timed[0][1]
            s.last = timed[-1][1]

    def run(self, progress: Progress | None) -> Iterator[pa.RecordBatch]:
        assert _native is not None
        cols = _native.Columns(self.table, WINDOW_FRAMES)
        with column_walker(self.path, self.kind, self.dialect, self.stage, self.dissector, cols) as (walker, _):
            yield from self._walk(walker, cols, progress)
            stats = walker.stats()
        self.size = int(stats["size"])
        if progress is not None:
            progress(int(stats["position"]))

    def _walk(self, walker: _native.Walker, cols: _native.Columns, progress: Progress | None,
              ) -> Iterator[pa.RecordBatch]:
        # windows of WINDOW_FRAMES rows, native and handed back together, less what the frames table carries
        # over (a handed-back record of several frames can overshoot a window): so that frames batches of as
        # many rows are windows as they are, not copies. The walker stops where the native rows fill the window.
        def goal() -> int:
            return WINDOW_FRAMES - self.pending.frames_held % WINDOW_FRAMES

        cols.limit = goal()
        for kind, items, at in column_steps(walker, cols, self.dissector, lambda: not self.stage.check_signatures):
            yield from self.python(items, at)
            if kind == FINISH:
                yield from self.window(cols.take())
                break
            if kind == DONE:
                if cols.frames + len(self.py) >= goal():
                    yield from self.window(cols.take())
                    if progress is not None:
                        progress(int(walker.stats()["position"]))
                cols.limit = goal() - len(self.py)  # > cols.frames here

    def settle(self) -> None:
        """The expert's detectors with the state of the whole capture (after `run`); and the audit's command
        matcher, from a pure pass where the capture sent more commands than it holds
        (native_commands.CommandKeys; else it gives up none, unfed)."""
        if not self.want_findings:
            return
        self.analyses.expert = self.expert
        if self.feed.commands.may_give_up:
            self.analyses.audit_pass.matcher = command_pass(self.path, self.options, self.dialect)

    def finish(self) -> Iterator[pa.RecordBatch]:
        yield from self.pending.flush()
        self.settle()
        found = self.analyses.findings() if self.want_findings else []
        if self.want_findings:
            yield findings_batch(self.capture_id, found)
        b = self.anomalies.flush()
        if b is not None:
            yield b
        yield captures_batch(self.capture_id, self.path, self.name, self.size, self.kind, self.summary,
                             self.anomalies.count, len(found) if self.want_findings else None, len(self.types),
                             self.dialect, self.options, NATIVE)


def native_source(path: str, capture_id: str, options: ExportOptions, progress: Progress | None,
                  warn: Warn | None) -> Iterator[pa.RecordBatch]:
    """The native batch source (the pure one where the extension is not built)."""
    if _native is None:
        yield from python_source(path, capture_id, options, progress, warn)
        return
    popts = replace(options.pipeline, display_filter=None)  # an export holds every frame
    dialect = dialect_for(popts)
    with open_capture(path) as reader:  # the capture's errors first, as the pure source's session gives them
        kind = reader.kind
    stage = make_security_stage(popts, warn or (lambda _m: None))
    export = _Export(path, kind, capture_id, options, dialect, stage)
    yield from export.run(progress)
    yield from export.finish()
