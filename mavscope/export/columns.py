"""Column builders: frames in, Arrow record batches out, a bounded number of rows at a time.

`FrameColumns` turns frames into frames-table batches column by column (each column one pass over a
chunk of frames). `MessageTables` keeps, per message type, the padded payloads of its decoded frames
and their identity; at a flush it unpacks them all with one `struct.iter_unpack` (the dialect's wire
format) and regroups arrays and strings; it bounds the rows held over every message type together,
so a capture of any length and mix is exported in bounded memory. `AnomalyColumns` does the same for
the problems that belong to no frame.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field

import pyarrow as pa

from mavscope.export.schema import (
    FRAME_COLUMNS,
    IDENTITY,
    anomalies_schema,
    frames_schema,
    has_block,
    message_columns,
)
from mavscope.mavlink.dialect import Dialect, MessageDef, bytes_text, char_text, is_text, wire_format
from mavscope.mavlink.frame import Frame, plaintext_payload
from mavscope.pipeline.dissect import Anomaly

DEFAULT_ROWS = 65_536  # rows per record batch (and so per Parquet row group)
ENUM_CACHE = 4096  # bitmask values whose names are remembered per field


class FrameColumns:
    """Frames -> frames-table batches of at most `rows` rows. Frames are turned into Arrow arrays
    `CHUNK` at a time, so that few Python objects stay alive (the garbage collector's full passes cost
    in proportion to them), and the arrays joined into one batch of `rows` rows (one row group)."""

    CHUNK = 8192

    def __init__(self, capture_id: str, capture_path: str, rows: int = DEFAULT_ROWS) -> None:
        self.capture_id = capture_id
        self.capture_path = capture_path
        self.rows = rows
        self.step = min(rows, self.CHUNK)
        self.schema = frames_schema()
        self.chunk: list[Frame] = []
        self.parts: list[pa.RecordBatch] = []
        self.held = 0

    def add(self, frame: Frame) -> pa.RecordBatch | None:
        """Keep `frame`; a batch when `rows` frames are kept."""
        chunk = self.chunk
        chunk.append(frame)
        if len(chunk) >= min(self.step, self.rows - self.held):  # never past `rows`
            self._convert()
            if self.held >= self.rows:
                return self.flush()
        return None

    def _convert(self) -> None:
        chunk, self.chunk = self.chunk, []
        if not chunk:
            return
        self.parts.append(frame_batch(self.capture_id, self.capture_path, chunk, self.schema))
        self.held += len(chunk)

    def flush(self) -> pa.RecordBatch | None:
        self._convert()
        parts, self.parts, self.held = self.parts, [], 0
        if not parts:
            return None
        if len(parts) == 1:
            return parts[0]
        return pa.Table.from_batches(parts, schema=self.schema).combine_chunks().to_batches()[0]


def frame_batch(capture_id: str, capture_path: str, chunk: list[Frame], schema: pa.Schema | None = None,
                ) -> pa.RecordBatch:
    """The frames-table rows of `chunk`, each column one pass over it."""
    n = len(chunk)
    arrays = [pa.array([capture_id] * n, pa.string()), pa.array([capture_path] * n, pa.string())]
    having: dict[str, list[Frame | None]] = {}  # per block: the frames that have it (None: not this one)
    for col in FRAME_COLUMNS:
        if col.block is None:
            arrays.append(pa.array(list(map(col.get, chunk)), col.type))
            continue
        rows = having.get(col.block)
        if rows is None:
            rows = having[col.block] = [f if has_block(col.block, f) else None for f in chunk]
            if not any(rows):
                rows = having[col.block] = []
        if not rows:
            arrays.append(pa.nulls(n, col.type))
        else:
            get = col.get
            arrays.append(pa.array([None if f is None else get(f) for f in rows], col.type))
    return pa.RecordBatch.from_arrays(arrays, schema=schema or frames_schema())


class AnomalyColumns:
    """Anomalies (problems that belong to no frame) -> anomalies-table batches, one row per note."""

    def __init__(self, capture_id: str, rows: int = DEFAULT_ROWS) -> None:
        self.capture_id = capture_id
        self.rows = rows
        self.pending: list[tuple[int, str, str, str, int | None]] = []
        self.count = 0

    def add(self, item: Anomaly) -> pa.RecordBatch | None:
        for n in item.notes:
            self.pending.append((item.record, n.code, n.severity.value, n.message, n.offset))
            self.count += 1
        return self.flush() if len(self.pending) >= self.rows else None

    def flush(self) -> pa.RecordBatch | None:
        rows, self.pending = self.pending, []
        if not rows:
            return None
        record, code, severity, message, offset = (list(c) for c in zip(*rows))
        return pa.RecordBatch.from_arrays(
            [pa.array([self.capture_id] * len(rows), pa.string()), pa.array(record, pa.int64()), pa.array(code),
             pa.array(severity), pa.array(message), pa.array(offset, pa.int64())], schema=anomalies_schema())


@dataclass
class _Plan:
    """How to turn one message's unpacked tuples into its columns."""

    md: MessageDef
    schema: pa.Schema
    unpack: struct.Struct
    # per field in wire order: (flat start, element count, kind: 0 scalar, 1 string, 2 array, 3 a char array of
    # a value's bytes: dialect.VALUE_BYTES)
    steps: list[tuple[int, int, int]]
    order: list[int]  # wire index of each column in XML order
    extensions: list[int]  # column positions (XML order) of extension fields
    names: list[tuple[int, dict[int, str], bool]]  # (column position, value -> name, bitmask) per _name column
    cache: list[dict[int, str | None]] = field(default_factory=list)


def _plan(md: MessageDef, dialect: Dialect) -> _Plan:
    cols = message_columns(md, dialect)
    wire = list(md.fields)
    steps = []
    i = 0
    for fd in wire:
        if fd.type == "char":
            steps.append((i, 1, 1 if is_text(fd) else 3))
            i += 1
        elif fd.array_length:
            steps.append((i, fd.array_length, 2))
            i += fd.array_length
        else:
            steps.append((i, 1, 0))
            i += 1
    position = {fd.name: k for k, fd in enumerate(wire)}
    order = [position[fd.name] for _, fd in cols.fields]
    extensions = [j for j, (_, fd) in enumerate(cols.fields) if fd.extension]
    col_of = {fd.name: j for j, (_, fd) in enumerate(cols.fields)}
    names = []
    for _, fd in cols.names:
        enum = dialect.enums[fd.enum]
        names.append((col_of[fd.name], {v: e.name for v, e in enum.entries.items()}, enum.bitmask))
    unpack = struct.Struct(wire_format(wire))
    return _Plan(md, cols.schema, unpack, steps, order, extensions, names, [{} for _ in names])


def flag_names(value: int, names: dict[int, str]) -> str | None:
    """A bitmask value as its set flags joined by "|" (unknown bits as hex); the zero entry's name for 0."""
    if not isinstance(value, int):
        return None
    if value == 0:
        return names.get(0, "")
    out, rest = [], value
    for bit, name in sorted(names.items()):
        if bit and value & bit == bit:
            out.append(name)
            rest &= ~bit
    if rest:
        out.append(f"0x{rest:x}")
    return "|".join(out)


class _Message:
    """The pending rows of one message type."""

    __slots__ = ("plan", "payloads", "ids", "v1")
    # The identity is kept as one list per column (numbers and strings: objects the garbage collector
    # does not track), not a tuple per row: hundreds of thousands of pending tuples made every full
    # collection walk them (30% of the export's time on a 1M-frame capture).

    def __init__(self, plan: _Plan) -> None:
        self.plan = plan
        self.payloads: list[bytes] = []
        self.ids: tuple[list[object], ...] = tuple([] for _ in IDENTITY)
        self.v1: list[int] = []  # rows from MAVLink 1 frames (no extension fields on the wire)

    def batch(self, capture_id: str) -> pa.RecordBatch:
        plan = self.plan
        n = len(self.payloads)
        flat = list(zip(*plan.unpack.iter_unpack(b"".join(self.payloads))))
        wire_cols: list[list[object]] = []
        for start, count, kind in plan.steps:
            if kind == 0:
                wire_cols.append(list(flat[start]))
            elif kind == 1:
                wire_cols.append([char_text(b) for b in flat[start]])
            elif kind == 3:
                wire_cols.append([bytes_text(b) for b in flat[start]])
            else:
                wire_cols.append([list(t) for t in zip(*flat[start : start + count])])
        values = [wire_cols[k] for k in plan.order]
        if self.v1:
            for j in plan.extensions:
                col = values[j] = list(values[j])
                for r in self.v1:
                    col[r] = None
        ident = self.ids
        arrays = [pa.array([capture_id] * n, pa.string())]
        arrays += [pa.array(ident[k], t) for k, (_, t, _) in enumerate(IDENTITY)]
        schema = plan.schema
        base = 1 + len(IDENTITY)
        arrays += [pa.array(v, schema.field(base + j).type) for j, v in enumerate(values)]
        for (j, names, bitmask), cache in zip(plan.names, plan.cache):
            ints: list[int | None] = values[j]  # type: ignore[assignment]  # an integer field's column
            if bitmask:
                out: list[str | None] = []
                for v in ints:
                    if v is None:
                        out.append(None)
                        continue
                    if v in cache:
                        out.append(cache[v])
                        continue
                    name = flag_names(v, names)
                    if len(cache) < ENUM_CACHE:
                        cache[v] = name
                    out.append(name)
                arrays.append(pa.array(out, pa.string()))
            else:
                get = names.get
                arrays.append(pa.array([None if v is None else get(v) for v in ints], pa.string()))
        self.payloads, self.ids, self.v1 = [], tuple([] for _ in IDENTITY), []
        return pa.RecordBatch.from_arrays(arrays, schema=schema)


class MessageTables:
    """Decoded frames -> one table per message type, batches of at most `rows` rows, and at most
    `4 * rows` rows held over all message types (the largest is flushed first)."""

    def __init__(self, capture_id: str, dialect: Dialect, rows: int = DEFAULT_ROWS) -> None:
        self.capture_id = capture_id
        self.dialect = dialect
        self.rows = rows
        self.limit = 4 * rows
        self.held = 0
        self.pending: dict[int, _Message] = {}
        self.counts: dict[str, int] = {}

    def add(self, frame: Frame) -> Iterator[pa.RecordBatch]:
        """Keep the decoded payload of `frame` (nothing for a frame that does not decode)."""
        payload = plaintext_payload(frame)
        if payload is None:
            return
        md: MessageDef = frame.msgdef  # type: ignore[assignment]  # plaintext_payload checked it
        msg = self.pending.get(md.id)
        if msg is None or msg.plan.md is not md:
            if msg is not None:  # another definition under the same id (cannot happen within one dialect)
                yield from self._flush(md.id)
            msg = self.pending[md.id] = _Message(_plan(md, self.dialect))
        length = md.length
        if len(payload) != length:
            payload = payload[:length] if len(payload) > length else payload + bytes(length - len(payload))
        if frame.version == 1:
            msg.v1.append(len(msg.payloads))
        msg.payloads.append(payload)
        record, index, time, sysid, compid, crc, sig_status = msg.ids
        record.append(frame.record)
        index.append(frame.index)
        time.append(frame.time)
        sysid.append(frame.sysid)
        compid.append(frame.compid)
        crc.append(frame.crc_status)  # str enums: Arrow takes them as their text
        sig_status.append(frame.signature_status)
        self.counts[md.name] = self.counts.get(md.name, 0) + 1
        self.held += 1
        if len(msg.payloads) >= self.rows:
            yield from self._flush(md.id)
        elif self.held > self.limit:
            yield from self._flush(max(self.pending, key=lambda k: len(self.pending[k].payloads)))

    def _flush(self, msgid: int) -> Iterator[pa.RecordBatch]:
        msg = self.pending[msgid]
        if msg.payloads:
            self.held -= len(msg.payloads)
            yield msg.batch(self.capture_id)

    def flush(self) -> Iterator[pa.RecordBatch]:
        for msgid in list(self.pending):
            yield from self._flush(msgid)
