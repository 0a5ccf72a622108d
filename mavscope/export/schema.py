"""The tables of an export dataset and their Arrow schemas (docs/dataset.md), versioned as one.

- `frames`: one row per MAVLink frame. Its columns are the field registry's JSON keys
  (`mavscope.fields.registry`, the same values `read -T jsonl` writes; the signature and encryption
  blocks flattened as `signature_status`, `encryption_scheme`...), with the capture id and path, the
  frame's note codes, its file offset and its payload bytes.
- `msg=<NAME>`: one row per decoded frame of message NAME, one typed column per field in XML order
  (units, enum and MAVLink type in the column metadata; an enum-valued field also as `<field>_name`),
  after the frame's identity (`_frame`, `_index`...: the underscore keeps them apart from fields called
  `frame` or `seq`). The schema comes from the dialect (pymavlink's parser), never written by hand.
- `findings`, `anomalies`, `captures`: what the analyses concluded, the problems that belong to no
  frame, and one row per capture.

Every table is partitioned by `capture_id` (the SHA-256 of the capture's bytes, in hex). Record
batches carry it as a column; the dataset writer moves it into the directory names (Hive style).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from operator import itemgetter

import pyarrow as pa

from mavscope.fields.registry import ENCRYPTION_BLOCK, FIELDS, FLOAT, INT, MISSING, SIGNATURE_BLOCK, STR, Field
from mavscope.mavlink.dialect import Dialect, FieldDef, MessageDef
from mavscope.mavlink.frame import SIGNING_EPOCH, Frame

SCHEMA_VERSION = 1
PARTITION = "capture_id"
FRAMES, FINDINGS, CAPTURES, ANOMALIES = "frames", "findings", "captures", "anomalies"
MESSAGE_PREFIX = "msg="
TABLE_KEY = b"mavscope.table"  # schema metadata: which table a record batch belongs to
VERSION_KEY = b"mavscope.schema_version"

Getter = Callable[[Frame], object]


_ID = b"SHA-256 of the capture file's bytes, hex (the Hive partition)"


def message_table(name: str) -> str:
    """The table of message `name`: "msg=HEARTBEAT"."""
    return MESSAGE_PREFIX + name


def table_of(batch: pa.RecordBatch | pa.Schema) -> str:
    """The table a record batch (or schema) belongs to."""
    schema = batch if isinstance(batch, pa.Schema) else batch.schema
    return (schema.metadata or {}).get(TABLE_KEY, b"").decode()


def _meta(table: str, extra: dict[str, str] | None = None) -> dict[bytes, bytes]:
    meta = {TABLE_KEY: table.encode(), VERSION_KEY: str(SCHEMA_VERSION).encode()}
    for k, v in (extra or {}).items():
        meta[f"mavscope.{k}".encode()] = v.encode()
    return meta


# --- frames -----------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Column:
    """One column of the frames table: its name, Arrow type, and how a frame gives its value (None: null)."""

    name: str
    type: pa.DataType
    get: Getter
    description: str = ""
    block: str | None = None  # SIGNATURE_BLOCK, ENCRYPTION_BLOCK: null on frames without that block


# Narrow integer types for the header fields (the registry knows only "int").
_WIDTH = {
    "frame": pa.int64(), "index": pa.int32(), "version": pa.uint8(), "len": pa.uint8(),
    "incompat_flags": pa.uint8(), "compat_flags": pa.uint8(), "seq": pa.uint8(), "sysid": pa.uint8(),
    "compid": pa.uint8(), "msgid": pa.uint32(), "crc": pa.uint16(), "signature_link_id": pa.uint8(),
    "signature_timestamp": pa.int64(), "encryption_method": pa.uint8(),
}
_BY_TYPE = {INT: pa.int64(), FLOAT: pa.float64(), STR: pa.string()}


def _signature_time(f: Frame) -> object:
    """The signature timestamp as microseconds since 1970 (a `timestamp[us, UTC]` column; the JSON's ISO text)."""
    s = f.signature
    return None if s is None else SIGNING_EPOCH * 1_000_000 + s.timestamp * 10


# Columns whose value is not the JSON's: a timestamp type instead of ISO text.
_OVERRIDES: dict[str, tuple[pa.DataType, Getter, str]] = {
    "signature_time": (pa.timestamp("us", tz="UTC"), _signature_time,
                       "the signature timestamp (10 us resolution; ISO-8601 text in the JSON)"),
}


def _column_name(f: Field) -> str:
    assert f.json_key is not None
    return f.json_key if f.json_block is None else f"{f.json_block}_{f.json_key}"


def _json_getter(f: Field) -> Getter:
    """The field's JSON value, MISSING as None. A value the frame holds as exported is read with one C call
    (`crc_status` is a `str` enum: Arrow takes it as its text)."""
    if f.attr is not None and f.json_get is None:
        return itemgetter(Frame._fields.index(f.attr))
    get = f.json_get or f.get

    def value(frame: Frame) -> object:
        v = get(frame)
        return None if v is MISSING else v

    return value


def has_block(block: str | None, frame: Frame) -> bool:
    """Whether `frame` has the JSON block `block` (its columns are null otherwise, as the JSON's block)."""
    if block == SIGNATURE_BLOCK:
        return frame.signature is not None
    if block == ENCRYPTION_BLOCK:
        return frame.security is not None and frame.security.encryption is not None
    return True


def _notes(f: Frame) -> object:
    return [n.code for n in f.notes] if f.notes else []


def _payload(f: Frame) -> object:
    return f.payload


def _registry_columns() -> tuple[Column, ...]:
    cols = []
    for f in FIELDS:
        if f.json_key is None:
            continue
        name = _column_name(f)
        if name in _OVERRIDES:
            typ, get, description = _OVERRIDES[name]
        else:
            typ, get, description = _WIDTH.get(name) or _BY_TYPE[f.type], _json_getter(f), f.description or f.label
        cols.append(Column(name, typ, get, description, f.json_block))
    return tuple(cols)


# Every column of the frames table after capture_id and capture_path, in order.
FRAME_COLUMNS: tuple[Column, ...] = _registry_columns() + (
    Column("notes", pa.list_(pa.string()), _notes, "codes of the frame's notes (docs/json-format.md)"),
    Column("offset", pa.int64(), itemgetter(Frame._fields.index("offset")),
           "file offset of the STX byte, where the frame lies contiguous in the file"),
    Column("payload", pa.binary(), _payload, "the payload bytes as on the wire (encrypted ones as sent)"),
)


def frames_schema() -> pa.Schema:
    """The frames table as record batches carry it (capture_id included)."""
    fields = [pa.field(PARTITION, pa.string(), nullable=False, metadata={b"description": _ID}),
              pa.field("capture_path", pa.string(), metadata={b"description": b"the path it was exported from"})]
    fields += [pa.field(c.name, c.type, metadata={b"description": c.description.encode()}) for c in FRAME_COLUMNS]
    return pa.schema(fields, metadata=_meta(FRAMES))


# --- message tables ---------------------------------------------------------------------------------

# The frame identity at the start of every message table (underscored: fields may be called `frame`, `seq`).
IDENTITY: tuple[tuple[str, pa.DataType, str], ...] = (
    ("_frame", pa.int64(), "frames.frame of this frame"),
    ("_index", pa.int32(), "frames.index of this frame"),
    ("_time", pa.float64(), "capture time, Unix seconds"),
    ("_sysid", pa.uint8(), "sender system id"),
    ("_compid", pa.uint8(), "sender component id"),
    ("_crc_status", pa.string(), "ok or bad (a frame with a bad CRC is decoded, as read -T jsonl does)"),
    ("_signature_status", pa.string(), "signature verdict; null for an unsigned frame"),
)
_SCALAR = {
    "float": pa.float32(), "double": pa.float64(), "int8_t": pa.int8(), "uint8_t": pa.uint8(),
    "uint8_t_mavlink_version": pa.uint8(), "int16_t": pa.int16(), "uint16_t": pa.uint16(), "int32_t": pa.int32(),
    "uint32_t": pa.uint32(), "int64_t": pa.int64(), "uint64_t": pa.uint64(),
}
NAME_SUFFIX = "_name"


def field_type(fd: FieldDef) -> pa.DataType:
    """A payload field's column type: a char array is a string, another array a list."""
    if fd.type == "char":
        return pa.string()
    t = _SCALAR[fd.type]
    return pa.list_(t) if fd.array_length else t


def has_enum_names(fd: FieldDef, dialect: Dialect) -> bool:
    """Whether field `fd` gets a `<field>_name` column: a scalar integer field naming a dialect enum."""
    return bool(fd.enum) and not fd.array_length and fd.type != "char" and fd.enum in dialect.enums


def _field_meta(fd: FieldDef) -> dict[bytes, bytes]:
    meta = {b"mavlink_type": (f"{fd.type}[{fd.array_length}]" if fd.array_length else fd.type).encode()}
    if fd.units:
        meta[b"units"] = fd.units.encode()
    if fd.enum:
        meta[b"enum"] = fd.enum.encode()
    if fd.display == "bitmask":
        meta[b"bitmask"] = b"true"
    if fd.extension:
        meta[b"extension"] = b"true"
    if fd.description:
        meta[b"description"] = fd.description.encode()
    return meta


@dataclass(frozen=True, slots=True)
class MessageColumns:
    """The payload columns of one message table: (column name, field) in XML order, and its schema."""

    fields: tuple[tuple[str, FieldDef], ...]
    names: tuple[tuple[str, FieldDef], ...]  # the `<field>_name` columns
    schema: pa.Schema


@lru_cache(maxsize=2048)
def message_columns(md: MessageDef, dialect: Dialect) -> MessageColumns:
    """The table layout of message `md` (cached per message definition and dialect)."""
    by_name = {fd.name: fd for fd in md.fields}
    order = [by_name[n] for n in md.xml_order if n in by_name] or list(md.fields)
    taken = {PARTITION} | {n for n, _, _ in IDENTITY}
    fields: list[tuple[str, FieldDef]] = []
    for fd in order:
        col = fd.name
        while col in taken:  # a user dialect's field called capture_id or _frame
            col += "_field"
        taken.add(col)
        fields.append((col, fd))
    names: list[tuple[str, FieldDef]] = []
    for col, fd in fields:
        if has_enum_names(fd, dialect):
            name = col + NAME_SUFFIX
            while name in taken:
                name += "_"
            taken.add(name)
            names.append((name, fd))
    arrow = [pa.field(PARTITION, pa.string(), nullable=False, metadata={b"description": _ID})]
    arrow += [pa.field(n, t, metadata={b"description": d.encode()}) for n, t, d in IDENTITY]
    arrow += [pa.field(col, field_type(fd), metadata=_field_meta(fd)) for col, fd in fields]
    arrow += [pa.field(n, pa.string(), metadata={b"enum": fd.enum.encode(), b"names": fd.name.encode()})
              for n, fd in names]
    meta = _meta(message_table(md.name), {"message": md.name, "msgid": str(md.id), "crc_extra": str(md.crc_extra),
                                          "source": md.source})
    return MessageColumns(tuple(fields), tuple(names), pa.schema(arrow, metadata=meta))


def message_schema(name: str, dialect: Dialect) -> pa.Schema:
    """The schema of message `name`'s table (KeyError for a message the dialect does not have)."""
    return message_columns(dialect.by_name[name], dialect).schema


# --- findings, anomalies, captures ------------------------------------------------------------------


def findings_schema() -> pa.Schema:
    return pa.schema([
        pa.field(PARTITION, pa.string(), nullable=False, metadata={b"description": _ID}),
        pa.field("source", pa.string(),
                 metadata={b"description": b"the command that reports it: stats, audit, objects, params"}),
        pa.field("code", pa.string()),
        pa.field("severity", pa.string()),
        pa.field("group", pa.string()),
        pa.field("message", pa.string()),
        pa.field("frames", pa.list_(pa.int64()), metadata={b"description": b"frame numbers (the first listed)"}),
        pa.field("rule", pa.string(), metadata={b"description": b"the detection rule's id (code rule; docs/rules.md)"}),
    ], metadata=_meta(FINDINGS))


def anomalies_schema() -> pa.Schema:
    return pa.schema([
        pa.field(PARTITION, pa.string(), nullable=False, metadata={b"description": _ID}),
        pa.field("record", pa.int64()),
        pa.field("code", pa.string()),
        pa.field("severity", pa.string()),
        pa.field("message", pa.string()),
        pa.field("offset", pa.int64()),
    ], metadata=_meta(ANOMALIES))


def captures_schema() -> pa.Schema:
    return pa.schema([
        pa.field(PARTITION, pa.string(), nullable=False, metadata={b"description": _ID}),
        pa.field("path", pa.string(), metadata={b"description": b"the path the capture was exported from"}),
        pa.field("name", pa.string()),
        pa.field("size", pa.int64()),
        pa.field("kind", pa.string(), metadata={b"description": b"pcap, pcapng, tlog or raw"}),
        pa.field("frame_count", pa.int64()),
        pa.field("anomaly_count", pa.int64()),
        pa.field("problem_count", pa.int64(), metadata={
            b"description": b"the problems `read` reports on stderr: anomalies and frame notes of damage to the file"}),
        pa.field("first_problem", pa.string(), metadata={b"description": b"the first of them, as `read` writes it"}),
        pa.field("finding_count", pa.int64()),
        pa.field("message_type_count", pa.int32()),
        pa.field("first_time", pa.float64()),
        pa.field("last_time", pa.float64()),
        pa.field("key_material", pa.bool_(), metadata={b"description": b"whether keys judged the signatures"}),
        pa.field("dialects", pa.list_(pa.string())),
        pa.field("batch_source", pa.string(),
                 metadata={b"description": b"the batch source that read it: native, python"}),
        pa.field("mavscope_version", pa.string()),
        pa.field("schema_version", pa.int32()),
        pa.field("exported_at", pa.timestamp("us", tz="UTC")),
    ], metadata=_meta(CAPTURES))


FIXED_TABLES = (FRAMES, FINDINGS, ANOMALIES, CAPTURES)
FIXED_SCHEMAS: dict[str, Callable[[], pa.Schema]] = {
    FRAMES: frames_schema, FINDINGS: findings_schema, ANOMALIES: anomalies_schema, CAPTURES: captures_schema,
}


# --- for readers without unsigned integers (Spark) --------------------------------------------------

_SIGNED = {pa.uint8(): pa.int16(), pa.uint16(): pa.int32(), pa.uint32(): pa.int64(), pa.uint64(): pa.decimal128(20, 0)}


def _signed_type(t: pa.DataType) -> pa.DataType:
    if pa.types.is_list(t):
        return pa.list_(_signed_type(t.value_type))
    return _SIGNED.get(t, t)


def signed_schema(schema: pa.Schema) -> pa.Schema:
    """`schema` with every unsigned integer widened to a signed type that holds all its values (uint64 as
    decimal(20, 0)): Spark has no unsigned types."""
    return pa.schema([f.with_type(_signed_type(f.type)) for f in schema], metadata=schema.metadata)


def signed_batch(batch: pa.RecordBatch) -> pa.RecordBatch:
    """`batch` cast to `signed_schema` (values unchanged)."""
    return batch.cast(signed_schema(batch.schema))
