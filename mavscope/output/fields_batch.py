"""`read -T fields` over column batches (`Session.batches`): the lines `FieldsWriter` writes frame by frame,
from a `FrameBatch`'s columns, without a `Frame` per row where the columns hold the answer.

Each `-e` field becomes a column of a value (or none) per row, or of several (an array, `ip.addr`), by the
first way that serves it:
- a header number the batch holds (`frame.number`, `frame.len`, `mavlink.seq`, `.sysid`, `.compid`,
  `.msgid`, `.version`): its column, as int64;
- a field whose value only depends on columns the batch holds (`KEYED`: the endpoints and transport for
  `frame.src`, `ip.*`, `udp.*`, `tcp.*`; the message label for `mavlink.msgname`; the CRC and signature
  verdicts): the registry's own getter on one row's `Frame` per distinct combination (`Coded`: the texts
  and each row's);
- `frame.time`, `frame.time_epoch`, `frame.time_relative`: output.timefmt.Clock.at over the time column;
- a scalar payload field of one message (`ATTITUDE.roll`): its values read from the payload bytes
  (FrameBatch.field_column; `Numbers`: float32 and the integers an int64 holds);
- another payload field (a bare `roll`, an array, a char array, a display-unit companion): the rows of its
  messages decoded per message in one call (FrameBatch.decoded, a bad CRC's payload too, as
  `decode_payload` does it) and the registry's own `PayloadField.value_at`, as text;
- any other field: the registry's getter on every row's `Frame` (FrameBatch.frames).
The lines of whole records are joined from the columns in one call (`join_cells`, or on the native
engine its C form `_native.join_fields`: the record's values picked or joined as `-E occurrence` says,
numbers written as `_text` writes them, cells quoted); a record that may go on across batches (the first
and last of a batch) goes through FieldsWriter's own aggregation. The lines are the frame-by-frame
writer's, byte for byte (tests/cli/test_fields_batch.py holds them to it, and the C joiner to its
reference).

`frame.time_delta` needs the time of every captured record, with or without MAVLink, and
`frame.time_delta_displayed` the last line's: those two, a display filter, `-w` and `-z` keep the
frame-by-frame writer (`serves`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import IO, Any

import numpy as np

from mavscope.fields.registry import MISSING, Field, FieldRegistry, PayloadField
from mavscope.mavlink.floats import f32_text
from mavscope.native.core import _native
from mavscope.output.fields_out import FieldsFormat, FieldsWriter, _accessor, _text
from mavscope.output.timefmt import Clock
from mavscope.pipeline.batch import FrameBatch

# header numbers a FrameBatch holds as columns: field -> column
DIRECT: dict[str, str] = {"frame.number": "record", "frame.len": "size", "mavlink.version": "version",
                          "mavlink.seq": "seq", "mavlink.sysid": "sysid", "mavlink.compid": "compid",
                          "mavlink.msgid": "msgid"}
# fields whose value is a function of these columns alone: field -> the columns
_ENDS = ("transport", "src", "dst")
KEYED: dict[str, tuple[str, ...]] = {
    "frame.transport": _ENDS, "frame.src": _ENDS, "frame.dst": _ENDS, "ip.src": _ENDS,
    "ip.dst": _ENDS, "ip.addr": _ENDS, "udp.srcport": _ENDS, "udp.dstport": _ENDS, "udp.port": _ENDS,
    "tcp.srcport": _ENDS, "tcp.dstport": _ENDS, "tcp.port": _ENDS, "mavlink.msgname": ("label",),
    "mavlink.crc_status": ("crc",), "signature": ("signed",), "signature.status": ("verdict",),
}
CLOCKED = frozenset({"frame.time", "frame.time_epoch", "frame.time_relative"})
UNSERVED = frozenset({"frame.time_delta", "frame.time_delta_displayed"})  # see the module docstring

# a column of occurrences: per row, its one value (None: the row has none) or its values (a list)
Occurrences = list[Any]  # (list[str | None] or list[list[str]]: one form a column)
Column = Callable[[FrameBatch, "_Frames"], Occurrences]


def serves(names: Sequence[str]) -> bool:
    """Whether the batch writer serves these `-e` fields (every one but the two of UNSERVED)."""
    return not UNSERVED.intersection(names)


class _Frames:
    """What a batch's columns share, made once: every row's Frame, and the rows of a set of messages with
    their decoded payloads."""

    def __init__(self, b: FrameBatch) -> None:
        self.b = b
        self._all: list | None = None
        self._decoded: dict[frozenset[str], tuple[list[int], list[dict[str, object] | None]]] = {}
        self._keys: dict[tuple[str, ...], tuple[list[int], np.ndarray]] = {}
        self._rows: dict[frozenset[str], list[int]] = {}

    def all(self) -> list:
        if self._all is None:
            self._all = self.b.frames(range(self.b.n))
        return self._all

    def keys(self, columns: tuple[str, ...]) -> tuple[list[int], np.ndarray]:
        """The distinct combinations of the `columns`' values: a row of each, and each row's combination
        (int64, numbering them)."""
        got = self._keys.get(columns)
        if got is None:
            got = self._keys[columns] = _distinct([getattr(self.b, c) for c in columns])
        return got

    def rows(self, names: frozenset[str]) -> list[int]:
        """The rows of messages `names`."""
        got = self._rows.get(names)
        if got is None:
            got = self._rows[names] = np.flatnonzero(self.b.of_messages(names)).tolist()
        return got

    def decoded(self, names: frozenset[str]) -> tuple[list[int], list[dict[str, object] | None]]:
        """The rows of messages `names` and their payloads, decoded (a bad CRC's too: `decode_payload`'s)."""
        got = self._decoded.get(names)
        if got is None:
            rows = self.rows(names)
            got = self._decoded[names] = (rows, self.b.decoded(rows, names, bad_crc=True) if rows else [])
        return got


def _direct(column: str) -> Column:
    def values(b: FrameBatch, _frames: _Frames) -> Occurrences:
        return getattr(b, column).astype(np.int64)  # (numbers: see _lines)
    return values


def _distinct(columns: list[np.ndarray]) -> tuple[list[int], np.ndarray]:
    """A row of each distinct combination of the columns' values, and each row's combination's number:
    the values offset into one number (a table as long as the product of their ranges, when that is no
    longer than four times the rows), else by sorting (np.unique)."""
    n = len(columns[0])
    key = np.zeros(n, np.int64)
    size = 1
    for col in columns:
        lo, hi = (int(col.min()), int(col.max())) if n else (0, 0)
        size *= hi - lo + 1
        if size > max(4 * n, 1 << 16):
            break
        key = key * (hi - lo + 1) + (col.astype(np.int64) - lo)
    else:
        row = np.full(size, -1, np.int64)
        row[key] = np.arange(n)  # (a row of each: any of them serves)
        present = np.flatnonzero(row >= 0)
        number = np.zeros(size, np.int64)
        number[present] = np.arange(len(present))
        return row[present].tolist(), number[key]
    key = np.zeros(n, np.int64)
    for col in columns:
        distinct, inverse = np.unique(col, return_inverse=True)
        key = key * len(distinct) + inverse.reshape(-1)
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return first.tolist(), inverse.reshape(-1).astype(np.int64)


class Coded:
    """A column of one value (or none) per row as a table of the distinct values and each row's number in
    it (a value that depends on a few columns alone: the registry's getter runs once per distinct one)."""

    __slots__ = ("texts", "ids")

    def __init__(self, texts: list[str | None], ids: np.ndarray) -> None:
        self.texts, self.ids = texts, ids

    def __len__(self) -> int:
        return len(self.ids)

    def __getitem__(self, k: Any) -> Any:
        if isinstance(k, slice):
            return Coded(self.texts, self.ids[k])
        return self.texts[int(self.ids[k])]


def _keyed(columns: tuple[str, ...], accessor: Callable) -> Column:
    def values(b: FrameBatch, frames: _Frames) -> Occurrences:
        if not b.n:
            return []
        first, ids = frames.keys(columns)
        texts = [accessor(f, None) for f in b.frames(first)]  # (those rows' Frames only)
        if all(len(t) <= 1 for t in texts):
            return Coded([t[0] if t else None for t in texts], ids)  # type: ignore[return-value]
        return [texts[k] for k in ids.tolist()]
    return values


def _clocked(clock: Clock, name: str) -> Column:
    at = clock.at

    def values(b: FrameBatch, _frames: _Frames) -> Occurrences:
        return [at(name, t, r) if ok else None
                for t, ok, r in zip(b.time.tolist(), b.timed.tolist(), b.record.tolist())]
    return values


# a scalar payload field's values as `_text` writes them: ints in decimal, float32 shortest, doubles repr
_SCALAR: dict[str, Callable[[Any], str]] = {
    **{t: str for t in ("int8_t", "uint8_t", "uint8_t_mavlink_version", "int16_t", "uint16_t", "int32_t",
                        "uint32_t", "int64_t", "uint64_t")},
    "float": f32_text, "double": repr,
}


# the scalar types a Numbers column holds: float32 ("f4") and the integers an int64 holds ("i8")
_NUMBERS = {"float": "f4", **{t: "i8" for t in ("int8_t", "uint8_t", "uint8_t_mavlink_version", "int16_t", "uint16_t",
                                               "int32_t", "uint32_t", "int64_t")}}
_NUMBER_TEXT: dict[str, Callable[[Any], str]] = {"f4": f32_text, "i8": str}


class Numbers:
    """A column of a payload number (or none) per row: `kind` f4 (float32, written as its shortest text) or
    i8 (an integer), the values and whether each row has one."""

    __slots__ = ("kind", "values", "present")

    def __init__(self, kind: str, values: np.ndarray, present: np.ndarray) -> None:
        self.kind, self.values, self.present = kind, values, present

    def __len__(self) -> int:
        return len(self.values)

    def __getitem__(self, k: Any) -> Any:
        if isinstance(k, slice):
            return Numbers(self.kind, self.values[k], self.present[k])
        return _NUMBER_TEXT[self.kind](self.values[k].item()) if self.present[k] else None


def _payload(field: PayloadField) -> Column:
    names = frozenset(fd.message for fd in field.defs.values())
    floats = {m: fd.type == "float" for m, fd in field.defs.items()}
    value_at = field.value_at
    # one message's field as it is (no companion's unit): the decoded payload's value
    plain = next(iter(field.defs.values())) if len(field.defs) == 1 and field.divisors is None else None

    def values(b: FrameBatch, frames: _Frames) -> Occurrences:
        out: list = [None] * b.n
        if plain is not None and not plain.array_length and plain.type in _SCALAR:
            rows = frames.rows(names)
            values, present = b.field_column(rows, plain)
            kind = _NUMBERS.get(plain.type)
            if kind is not None:  # (the joiner writes them)
                full = np.zeros(b.n, values.dtype if kind == "f4" else np.int64)
                there = np.zeros(b.n, np.bool_)
                full[rows], there[rows] = values, present
                return Numbers(kind, full, there)  # type: ignore[return-value]
            text = _SCALAR[plain.type]  # (_text's text of the type's values)
            for r, value, ok in zip(rows, values.tolist(), present.tolist()):
                if ok:
                    out[r] = text(value)
            return out
        rows, decoded = frames.decoded(names)
        multi = False
        if plain is not None:
            name, f32 = plain.name, plain.type == "float"
            for r, fields in zip(rows, decoded):
                value = MISSING if fields is None else fields.get(name, MISSING)
                if value is MISSING:
                    continue
                if isinstance(value, list):
                    out[r] = [_text(v, f32) for v in value]
                    multi = True
                else:
                    out[r] = _text(value, f32)
        else:
            defs, msgids, labels = b.tables.label_defs, b.msgid, b.label
            for r, fields in zip(rows, decoded):
                msgid = int(msgids[r])
                value = value_at(msgid, defs[int(labels[r])], fields)
                if value is MISSING:
                    continue
                f32 = floats[msgid]
                if isinstance(value, list):
                    out[r] = [_text(v, f32) for v in value]
                    multi = True
                else:
                    out[r] = _text(value, f32)
        if multi:  # (a column is of one form)
            out = [[] if v is None else v if isinstance(v, list) else [v] for v in out]
        return out
    return values


def _framed(accessor: Callable) -> Column:
    def values(_b: FrameBatch, frames: _Frames) -> Occurrences:
        return [accessor(f, None) for f in frames.all()]
    return values


class BatchFieldsWriter(FieldsWriter):
    """A FieldsWriter that also takes whole batches (`batch`); frames given one by one (`frame`) as it does."""

    def __init__(self, out: IO[str], registry: FieldRegistry, names: Sequence[str], fmt: FieldsFormat,
                 clock: Clock | None = None, *, native: bool = False) -> None:
        """`native`: the session runs on the native engine, whose line joiner (`_native.join_fields`) joins
        the cells; else `join_cells`."""
        super().__init__(out, registry, names, fmt, clock)
        self.join: Join = \
            _native.join_fields if native and _native is not None else join_cells
        self.columns: list[Column] = []
        for name in names:
            got = registry.lookup(name)
            if name in CLOCKED:
                self.columns.append(_clocked(self.clock, name))
            elif isinstance(got, PayloadField):
                self.columns.append(_payload(got))
            elif isinstance(got, Field) and got.name in DIRECT:
                self.columns.append(_direct(DIRECT[got.name]))
            elif isinstance(got, Field) and got.name in KEYED:
                self.columns.append(_keyed(KEYED[got.name], _accessor(registry, name)[0]))
            else:
                self.columns.append(_framed(_accessor(registry, name)[0]))

    def batch(self, b: FrameBatch, limit: int | None = None) -> int:
        """The lines of batch `b`'s rows (its first `limit` only, with a limit); the rows taken. The rows of a
        record (a group) go through FieldsWriter's aggregation where the record may go on across batches:
        the first group when it goes on with the record being gathered, the last, which the next batch may
        go on with; the groups between are whole records, written from the columns (`_lines`)."""
        n = b.n if limit is None else min(b.n, limit)
        if not n:
            return 0
        frames = _Frames(b)
        occ = [column(b, frames)[:n] for column in self.columns]
        record = b.record[:n]
        bounds = [*np.flatnonzero(np.r_[True, record[1:] != record[:-1]]).tolist(), n]
        groups = len(bounds) - 1
        lo = 0
        if self.record is not None and int(record[0]) == self.record:
            self._take(occ, range(bounds[0], bounds[1]), record)
            lo = 1
        if groups - 1 > lo:
            self._flush()
            self.out.write(self._lines(occ, bounds, range(lo, groups - 1)))
        if groups - 1 >= lo:
            self._take(occ, range(bounds[groups - 1], n), record)
        return n

    def _take(self, occ: list[Occurrences], rows: range, record: np.ndarray) -> None:
        """Rows into the record being gathered (FieldsWriter.frame's aggregation)."""
        for r in rows:
            number = int(record[r])
            first = number != self.record
            if first:
                self._flush()
                self.record = number
            for got, column, per_record in zip(self.values, occ, self.per_record):
                if first or not per_record:
                    v = column[r]
                    if isinstance(v, list):
                        got.extend(v)
                    elif isinstance(v, np.integer):
                        got.append(str(v))
                    elif v is not None:
                        got.append(v)

    def _lines(self, occ: list[Occurrences], bounds: list[int], groups: range) -> str:
        """The lines of whole records: group `g` is the rows bounds[g]..bounds[g + 1] (FieldsWriter._flush's
        cells, from the columns). A column of a value (or none) per row goes to the joiner as it is, which
        picks or joins a record's (join_cells); a column of several values per row (an array, `ip.addr`)
        becomes a cell per record here."""
        fmt = self.fmt
        agg, how = fmt.aggregator, fmt.occurrence
        edges = np.asarray(bounds[groups.start:groups.stop + 1], np.int64)
        cells: list[Any] = []
        modes = bytearray()
        many: list[int] | None = None
        for column, per_record in zip(occ, self.per_record):
            modes.append(ord("r" if per_record else how))
            if isinstance(column, np.ndarray):  # header numbers
                cells.append(column)
            elif isinstance(column, Coded):
                cells.append((column.texts, column.ids))
            elif isinstance(column, Numbers):
                cells.append((column.kind, column.values, column.present))
            elif not (column and isinstance(column[0], list)):
                cells.append((column, None))
            else:  # each row's occurrences: a record's, those of each of its frames
                if many is None:  # (the records of several frames)
                    many = (np.flatnonzero(np.diff(edges) > 1) + groups.start).tolist()
                values = [column[s] for s in bounds[groups.start:groups.stop]]
                if not per_record:
                    for g in many:
                        values[g - groups.start] = [v for row in column[bounds[g]:bounds[g + 1]] for v in row]
                cells.append([agg.join(v if how == "a" else v[:1] if how == "f" else v[-1:]) if v else None
                              for v in values])
        return self.join(cells, edges, bytes(modes), fmt.separator, fmt.quote, agg)


Join = Callable[[list[Any], Any, bytes, str, str, str], str]  # (join_cells, _native.join_fields)


def join_cells(cells: list[Any], bounds: np.ndarray, modes: bytes, separator: str, quote: str,
               aggregator: str) -> str:
    """The lines of records: line g is rows bounds[g]..bounds[g + 1]. A column is a list of a cell per line
    (str, or None: no value, an empty cell), or a value per row: an int64 array of numbers, a pair (the
    distinct texts, each str or None, and an int64 array of each row's text's position among them; None:
    the texts are the rows'), or a triple (kind, values, present: a bool per row) of payload numbers, kind
    `f4` float32 values written as their shortest text (f32_text), `i8` int64 values; of a
    value per row, the cell is the record's first row's (mode `r`), or of the values its rows have (None
    has none) the first (`f`), the last (`l`) or all joined by `aggregator` (`a`), empty when none has one.
    A line's cells are joined by `separator`, each with a value in `quote` (a quote inside doubled, the
    aggregator's too). The reference of the native engine's `_native.join_fields` (the same arguments)."""
    edges = bounds.tolist()
    starts, ends = edges[:-1], edges[1:]
    cols = []
    qq = quote * 2
    for column, mode in zip(cells, modes):
        if isinstance(column, (np.ndarray, tuple)):
            if isinstance(column, np.ndarray):
                rows: list[str | None] = list(map(str, column.tolist()))
            elif len(column) == 3:  # (kind, values, present)
                text = _NUMBER_TEXT[column[0]]
                rows = [text(v) if ok else None for v, ok in zip(column[1].tolist(), column[2].tolist())]
            else:
                texts, ids = column
                rows = texts if ids is None else [texts[k] for k in ids.tolist()]
            if mode == ord("r"):
                column = [rows[a] for a in starts]
            else:
                column = []
                for a, z in zip(starts, ends):
                    got = [v for v in rows[a:z] if v is not None]
                    column.append(None if not got else got[0] if mode == ord("f") else got[-1]
                                  if mode == ord("l") else aggregator.join(got))
        if quote:
            cols.append(["" if v is None else f"{quote}{v.replace(quote, qq)}{quote}" for v in column])
        else:
            cols.append(["" if v is None else v for v in column])
    return "".join(line + "\n" for line in map(separator.join, zip(*cols)))
