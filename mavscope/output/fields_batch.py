"""`read -T fields` over column batches (`Session.batches`): the lines `FieldsWriter` writes frame by frame,
from a `FrameBatch`'s columns, without a `Frame` per row where the columns hold the answer.

Each `-e` field becomes a column of occurrences per row, by the first way that serves it:
- a header number the batch holds (`frame.number`, `frame.len`, `mavlink.seq`, `.sysid`, `.compid`,
  `.msgid`, `.version`): its column as text;
- a field whose value only depends on columns the batch holds (`KEYED`: the endpoints and transport for
  `frame.src`, `ip.*`, `udp.*`, `tcp.*`; the message label for `mavlink.msgname`; the CRC and signature
  verdicts): the registry's own getter on one row's `Frame` per distinct key, that row's text for every row
  of the key;
- `frame.time`, `frame.time_epoch`, `frame.time_relative`: output.timefmt.Clock.at over the time column;
- a payload field (`ATTITUDE.roll`, a bare `roll`, a display-unit companion): the rows of its messages
  decoded per message in one call (FrameBatch.decoded, a bad CRC's payload too, as `decode_payload` does
  it) and the registry's own `PayloadField.value_at`;
- any other field: the registry's getter on every row's `Frame` (FrameBatch.frames).
Values are written as FieldsWriter writes them (`_text`), and a record whose frames share a line (several
in a datagram, or a record cut across two batches) goes through FieldsWriter's own aggregation, so the
lines are the frame-by-frame writer's, byte for byte (tests/cli/test_fields_batch.py holds them to it).

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
        self._keys: dict[tuple[str, ...], tuple[list[int], list[int]]] = {}
        self._rows: dict[frozenset[str], list[int]] = {}

    def all(self) -> list:
        if self._all is None:
            self._all = self.b.frames(range(self.b.n))
        return self._all

    def keys(self, columns: tuple[str, ...]) -> tuple[list[int], list[int]]:
        """The distinct combinations of the `columns`' values: the first row of each, and each row's."""
        got = self._keys.get(columns)
        if got is None:
            b = self.b
            key = np.zeros(b.n, np.int64)
            for c in columns:  # (one number per distinct combination)
                distinct, inverse = np.unique(getattr(b, c), return_inverse=True)
                key = key * len(distinct) + inverse.reshape(-1)
            _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
            got = self._keys[columns] = (first.tolist(), inverse.reshape(-1).tolist())
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


def _keyed(columns: tuple[str, ...], accessor: Callable) -> Column:
    def values(b: FrameBatch, frames: _Frames) -> Occurrences:
        if not b.n:
            return []
        first, at = frames.keys(columns)
        texts = [accessor(b.frame(r), None) for r in first]
        if all(len(t) <= 1 for t in texts):
            one = [t[0] if t else None for t in texts]
            return [one[k] for k in at]
        return [texts[k] for k in at]
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
            text = _SCALAR[plain.type]  # (_text's text of the type's values)
            for r, value in zip(rows, b.field_values(rows, plain)):
                if value is not None:
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
        cells, from the columns: a header number's as the rows' numbers, the joiner picks and joins them)."""
        fmt = self.fmt
        agg, how = fmt.aggregator, fmt.occurrence
        starts = bounds[groups.start:groups.stop]
        many = [g for g in groups if bounds[g + 1] - bounds[g] > 1]  # records of several frames
        cells: list[Any] = []
        modes = bytearray()
        for column, per_record in zip(occ, self.per_record):
            modes.append(ord("f" if per_record else how))
            if isinstance(column, np.ndarray):  # header numbers, one per row
                cells.append(column)
                continue
            multi = bool(column) and isinstance(column[0], list)
            # (every record of one frame: its rows; else the first of each record's)
            values: list = column[starts[0]:bounds[groups.stop]] if not many else [column[s] for s in starts]
            if multi:  # each row's occurrences: a record's, those of each of its frames
                if many and not per_record:
                    for g in many:
                        values[g - groups.start] = [v for row in column[bounds[g]:bounds[g + 1]] for v in row]
                values = [agg.join(v if how == "a" else v[:1] if how == "f" else v[-1:]) if v else None
                          for v in values]
            elif many and not per_record:
                for g in many:
                    got = [v for v in column[bounds[g]:bounds[g + 1]] if v is not None]
                    values[g - groups.start] = (agg.join(got) if how == "a" else got[0] if how == "f" else got[-1]
                                                ) if got else None
            cells.append(values)
        edges = np.asarray(bounds[groups.start:groups.stop + 1], np.int64)
        return self.join(cells, edges, bytes(modes), fmt.separator, fmt.quote, agg)


Join = Callable[[list[Any], Any, bytes, str, str, str], str]  # (join_cells, _native.join_fields)


def join_cells(cells: list[Any], bounds: np.ndarray, modes: bytes, separator: str, quote: str,
               aggregator: str) -> str:
    """The lines of records: line g is rows bounds[g]..bounds[g + 1]. Each column is a list of a cell per
    line (str, or None: no value, an empty cell) or an int64 array of a number per row, of which the
    record's first (mode `f`), last (`l`) or all joined by `aggregator` (`a`) make the cell. A line's cells
    are joined by `separator`, each with a value in `quote` (a quote inside doubled). The reference of the
    native engine's `_native.join_fields` (the same arguments)."""
    edges = bounds.tolist()
    starts, ends = edges[:-1], edges[1:]
    cols = []
    qq = quote * 2
    for column, mode in zip(cells, modes):
        if isinstance(column, np.ndarray):
            texts = list(map(str, column.tolist()))
            if mode == ord("f"):
                column = [texts[a] for a in starts]
            elif mode == ord("l"):
                column = [texts[z - 1] for z in ends]
            else:
                column = [aggregator.join(texts[a:z]) for a, z in zip(starts, ends)]
        if quote:
            cols.append(["" if v is None else f"{quote}{v.replace(quote, qq)}{quote}" for v in column])
        else:
            cols.append(["" if v is None else v for v in column])
    return "".join(line + "\n" for line in map(separator.join, zip(*cols)))
