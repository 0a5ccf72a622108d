"""Arrow record batches from the C extension's column chunks (the export's native batch source).

A `Chunk` is what `_native.Columns.take()` hands over: per frame, fixed-width columns in buffers the C
walker grew (read-only `Block`s), the payloads and whole frames as Arrow-style binary columns, and per
message the payloads zero-extended to the message's length. Here they become the frames table's and the
message tables' columns without a copy where Arrow's layout is the buffer's (numbers, payloads), and with
vectorised numpy and Arrow kernels elsewhere (strings from tables of names, hex, validity bitmaps). A
message's payload rows are read through a numpy structured dtype compiled from its FieldDefs (pymavlink's
parser): the layout is never written here. Values equal the pure path's (columns.py) exactly: char arrays
cut at their first NUL and decoded as `char_text` does, float32 NaNs quieted as CPython's float conversion quiets them,
MAVLink 1 frames' extension fields null, enum names looked up per distinct value by the same rule.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import pyarrow as pa

from mavscope.export.columns import flag_names
from mavscope.export.schema import frames_schema, message_columns
from mavscope.mavlink.dialect import Dialect, FieldDef, MessageDef, bytes_text, char_text, is_text
from mavscope.mavlink.frame import SIGNING_EPOCH
from mavscope.native.chunk import Chunk
from mavscope.native.core import COLUMN_TRANSPORTS

# MAVLink scalar types as numpy types (sizes and offsets come from the FieldDefs)
_NUMPY = {
    "float": "f4", "double": "f8", "int8_t": "i1", "uint8_t": "u1", "uint8_t_mavlink_version": "u1",
    "int16_t": "i2", "uint16_t": "u2", "int32_t": "i4", "uint32_t": "u4", "int64_t": "i8", "uint64_t": "u8",
}
_HEX = np.frombuffer(b"0123456789abcdef", np.uint8)
_TRANSPORTS = pa.array(list(COLUMN_TRANSPORTS), pa.string())  # the transport column's codes -> names
LITTLE = sys.byteorder == "little"


def _buf(a: np.ndarray | object) -> pa.Buffer:
    return pa.py_buffer(a)


def _bitmap(mask: np.ndarray) -> pa.Buffer | None:
    """An Arrow validity bitmap of `mask` (True: valid), None when every row is valid."""
    if mask.all():
        return None
    return pa.py_buffer(np.packbits(mask.astype(np.bool_), bitorder="little"))


def constant(text: str, n: int) -> pa.Array:
    """`text` in each of `n` rows."""
    data = text.encode()
    offsets = np.arange(n + 1, dtype=np.int32) * len(data)
    return pa.Array.from_buffers(pa.string(), n, [None, _buf(offsets), pa.py_buffer(data * n)])


def masked_constant(text: str, mask: np.ndarray) -> pa.Array:
    """`text` where `mask` is set, null elsewhere."""
    n = len(mask)
    if not mask.any():
        return pa.nulls(n, pa.string())
    data = text.encode()
    offsets = np.zeros(n + 1, np.int32)
    np.cumsum(mask * np.int32(len(data)), out=offsets[1:])
    return pa.Array.from_buffers(pa.string(), n, [_bitmap(mask), _buf(offsets), pa.py_buffer(data * int(mask.sum()))])


def numbers(values: np.ndarray, typ: pa.DataType, valid: np.ndarray | None = None) -> pa.Array:
    """A numeric column over `values` (its buffer, not a copy, where contiguous and in native order)."""
    values = np.ascontiguousarray(values)
    bitmap = None if valid is None else _bitmap(valid)
    return pa.Array.from_buffers(typ, len(values), [bitmap, _buf(values)])


def quiet_nans(values: np.ndarray) -> np.ndarray:
    """float32 values as CPython's struct and float conversions leave them: a signalling NaN comes back
    quiet (the quiet bit set, the rest of its payload kept), as x86's float -> double -> float does."""
    if not np.isnan(values).any():
        return values
    bits = values.view(np.uint32).copy()
    nan = ((bits & 0x7F800000) == 0x7F800000) & ((bits & 0x007FFFFF) != 0)
    bits[nan] |= 0x00400000
    return bits.view(np.float32)


@dataclass(frozen=True)
class Names:
    """Text columns' values by id: the endpoints' "ip:port" and the table's message names."""

    endpoints: pa.Array
    messages: pa.Array


def _take(values: pa.Array, ids: np.ndarray) -> pa.Array:
    """values[ids], null where an id is negative."""
    mask = ids < 0
    return values.take(pa.array(ids, pa.int32(), mask=mask if mask.any() else None))


def frames_batch(c: Chunk, names: Names, capture_id: str, capture_path: str) -> pa.RecordBatch:
    """The frames-table rows of a chunk (every frame clean: CRC ok, no note, plaintext, no verdict but
    `no-key` on signed frames), the pure path's values."""
    n = c.n
    signed = c.signed
    stamp = SIGNING_EPOCH * 1_000_000 + c.sig_time * 10
    hexed = np.empty((n, 12), np.uint8)
    hexed[:, 0::2] = _HEX[c.sig_value >> 4]
    hexed[:, 1::2] = _HEX[c.sig_value & 15]
    value_at = np.zeros(n + 1, np.int32)
    np.cumsum(signed * np.int32(12), out=value_at[1:])
    value = pa.Array.from_buffers(pa.string(), n, [_bitmap(signed), _buf(value_at),
                                                   pa.py_buffer(hexed[signed].tobytes())])
    b = c.blocks
    cols: dict[str, pa.Array] = {
        "capture_id": constant(capture_id, n),
        "capture_path": constant(capture_path, n),
        "frame": numbers(c.record, pa.int64()),
        "index": numbers(c.index, pa.int32()),
        "time": numbers(c.time, pa.float64(), c.time_ok),
        "transport": _TRANSPORTS.take(pa.array(c.transport, pa.uint8())),
        "src": _take(names.endpoints, c.src),
        "dst": _take(names.endpoints, c.dst),
        "version": numbers(c.version, pa.uint8()),
        "len": numbers(c.len, pa.uint8()),
        "incompat_flags": numbers(c.iflags, pa.uint8()),
        "compat_flags": numbers(c.cflags, pa.uint8()),
        "seq": numbers(c.seq, pa.uint8()),
        "sysid": numbers(c.sysid, pa.uint8()),
        "compid": numbers(c.compid, pa.uint8()),
        "msgid": numbers(c.msgid, pa.uint32()),
        "msgname": names.messages.take(pa.array(c.message, pa.int32())),
        "crc": numbers(c.crc, pa.uint16()),
        "crc_status": constant("ok", n),
        "signature_link_id": numbers(c.sig_link, pa.uint8(), signed),
        "signature_timestamp": numbers(c.sig_time, pa.int64(), signed),
        "signature_time": numbers(stamp, pa.timestamp("us", tz="UTC"), signed),
        "signature_value": value,
        "signature_status": masked_constant("no-key", signed),
        "notes": pa.ListArray.from_arrays(pa.array(np.zeros(n + 1, np.int32)), pa.array([], pa.string())),
        "offset": numbers(c.offset, pa.int64()),
        "payload": pa.Array.from_buffers(pa.binary(), n, [None, _buf(b["payload_at"]), _buf(b["payload"])])
        if n else pa.array([], pa.binary()),
    }
    schema = frames_schema()
    arrays = [cols[f.name] if f.name in cols else pa.nulls(n, f.type) for f in schema]
    return pa.RecordBatch.from_arrays(arrays, schema=schema)


@dataclass(frozen=True)
class _Column:
    field: str  # its name in the dtype
    type: pa.DataType
    kind: int  # 0 number, 1 string (char array), 2 list, 3 a char array of a value's bytes (VALUE_BYTES)
    count: int  # elements (a char array: bytes)
    extension: bool
    float32: bool


@dataclass(frozen=True)
class MessagePlan:
    """How the payload rows of one message become its table's columns."""

    md: MessageDef
    schema: pa.Schema
    dtype: np.dtype
    columns: tuple[_Column, ...]  # XML order, as the schema
    names: tuple[tuple[int, dict[int, str], bool], ...]  # (column position, value -> name, bitmask)
    wire: tuple[str, ...]  # the field names in wire order (the dtype's order)
    simple: bool  # scalar fields only (no array, no char)


def _numpy_type(fd: FieldDef) -> str:
    return "=" + _NUMPY[fd.type]


@lru_cache(maxsize=2048)
def message_plan(md: MessageDef, dialect: Dialect) -> MessagePlan:
    """The plan of message `md` (cached per message definition and dialect)."""
    cols = message_columns(md, dialect)
    formats: list[str | tuple[str, tuple[int]]] = []
    offsets: list[int] = []
    dnames: list[str] = []
    for k, fd in enumerate(md.fields):
        dnames.append(f"f{k}")
        offsets.append(fd.offset)
        if fd.type == "char":
            formats.append(f"V{max(fd.array_length, 1)}")
        elif fd.array_length:
            formats.append((_numpy_type(fd), (fd.array_length,)))
        else:
            formats.append(_numpy_type(fd))
    dtype = np.dtype({"names": dnames, "formats": formats, "offsets": offsets, "itemsize": md.length})
    key = {fd.name: f"f{k}" for k, fd in enumerate(md.fields)}
    columns = []
    for (col, fd), field in zip(cols.fields, list(cols.schema)[8:]):
        assert field.name == col
        kind = (1 if is_text(fd) else 3) if fd.type == "char" else (2 if fd.array_length else 0)
        count = max(fd.array_length, 1)
        columns.append(_Column(key[fd.name], field.type, kind, count, fd.extension, fd.type == "float"))
    position = {fd.name: j for j, (_, fd) in enumerate(cols.fields)}
    names = []
    for _, fd in cols.names:
        enum = dialect.enums[fd.enum]
        names.append((position[fd.name], {v: e.name for v, e in enum.entries.items()}, enum.bitmask))
    simple = all(fd.array_length == 0 and fd.type != "char" for fd in md.fields)
    return MessagePlan(md, cols.schema, dtype, tuple(columns), tuple(names), tuple(fd.name for fd in md.fields),
                       simple)


def decoded(plan: MessagePlan, rows: Any, count: int) -> list[dict[str, object]]:
    """`md.decode` of each of `count` zero-extended payload rows of a message of scalar fields only
    (`plan.simple`): the same dict, its values unpacked by numpy instead of struct (ints; floats widened
    from float32 as CPython widens them, a signalling NaN quieted alike)."""
    assert plan.simple
    names = plan.wire
    return [dict(zip(names, t)) for t in np.frombuffer(rows, plan.dtype, count=count).tolist()]


def _strings(raw: np.ndarray, valid: np.ndarray | None, text: bool = True) -> pa.Array:
    """char arrays (rows of bytes) as `char_text` makes them (`text`: the bytes up to the first NUL) or
    `bytes_text` (else: all but the trailing NULs), UTF-8, bytes that are not UTF-8 as \\xNN escapes (the
    rare column holding one is decoded row by row, by those functions themselves)."""
    n, width = raw.shape
    if text:
        zero = raw == 0
        lengths = np.where(zero.any(axis=1), np.argmax(zero, axis=1), width).astype(np.int32)
    else:
        nonzero = raw != 0
        lengths = np.where(nonzero.any(axis=1), width - np.argmax(nonzero[:, ::-1], axis=1), 0).astype(np.int32)
    offsets = np.zeros(n + 1, np.int32)
    np.cumsum(lengths, out=offsets[1:])
    keep = np.arange(width)[None, :] < lengths[:, None]
    data = raw[keep].tobytes()
    bitmap = None if valid is None else _bitmap(valid)
    out = pa.Array.from_buffers(pa.string(), n, [bitmap, _buf(offsets), pa.py_buffer(data)])
    try:
        out.validate(full=True)
    except pa.ArrowInvalid:  # not UTF-8 somewhere
        decode = char_text if text else bytes_text
        rows = [decode(bytes(r)) for r in raw]
        out = pa.array(rows if valid is None else [t if v else None for t, v in zip(rows, valid)], pa.string())
    return out


def _values(col: _Column, recs: np.ndarray, valid: np.ndarray | None) -> tuple[pa.Array, np.ndarray | None]:
    """One payload column, and its numbers (for the enum names) when it is a scalar number."""
    raw = np.ascontiguousarray(recs[col.field])
    n = len(recs)
    if col.kind in (1, 3):
        return _strings(raw.view(np.uint8).reshape(n, col.count), valid, col.kind == 1), None
    if col.float32:
        raw = quiet_nans(raw)
    if col.kind == 0:
        return numbers(raw, col.type, valid), raw
    flat = raw.reshape(-1)
    values = pa.Array.from_buffers(col.type.value_type, len(flat), [None, _buf(flat)])
    offsets = np.arange(0, (n + 1) * col.count, col.count, dtype=np.int32)
    bitmap = None if valid is None else _bitmap(valid)
    return pa.Array.from_buffers(col.type, n, [bitmap, _buf(offsets)], children=[values]), None


def _enum_names(values: np.ndarray, names: dict[int, str], bitmask: bool, valid: np.ndarray | None) -> pa.Array:
    """The `<field>_name` column: each distinct value named once, as the pure path names it."""
    distinct, inverse = np.unique(values, return_inverse=True)
    named = [flag_names(v, names) if bitmask else names.get(v) for v in distinct.tolist()]
    mask = None if valid is None else ~valid
    return pa.array(named, pa.string()).take(pa.array(inverse.reshape(-1), pa.int32(), mask=mask))


def message_batch(plan: MessagePlan, rows: Any, frames: np.ndarray, c: Chunk, capture_id: str) -> pa.RecordBatch:
    """The table rows of one message's payload `rows` (zero-extended, one per frame), whose frames are at
    positions `frames` of chunk `c`."""
    n = len(frames)
    recs = np.frombuffer(rows, plan.dtype, count=n)
    v1 = c.version[frames] == 1
    ext_valid = ~v1 if v1.any() else None
    signed = c.signed[frames]
    arrays = [
        constant(capture_id, n),
        numbers(c.record[frames], pa.int64()),
        numbers(c.index[frames], pa.int32()),
        numbers(c.time[frames], pa.float64(), c.time_ok[frames]),
        numbers(c.sysid[frames], pa.uint8()),
        numbers(c.compid[frames], pa.uint8()),
        constant("ok", n),
        masked_constant("no-key", signed),
    ]
    numeric: list[np.ndarray | None] = []
    valids: list[np.ndarray | None] = []
    for col in plan.columns:
        valid = ext_valid if col.extension else None
        arr, nums = _values(col, recs, valid)
        arrays.append(arr)
        numeric.append(nums)
        valids.append(valid)
    for j, names, bitmask in plan.names:
        nums = numeric[j]
        assert nums is not None  # a scalar integer field
        arrays.append(_enum_names(nums, names, bitmask, valids[j]))
    return pa.RecordBatch.from_arrays(arrays, schema=plan.schema)
