"""The message layouts as the byte string the C extension's `Table` takes (src/mavscope_native/table.h).

Compiled from mavscope's MessageDef/FieldDef, so from pymavlink's parser: never written by hand. Both the
native `read` path (mavscope.native.walk) and the export's native batch source (mavscope.native.export) hand it
to C.
"""

from __future__ import annotations

import struct

import orjson

from mavscope.mavlink.dialect import Dialect, MessageDef

TABLE_MAGIC = b"MSNT"
TABLE_VERSION = 1

# MavLink wire type -> (native type code, bytes per element); the codes of src/mavscope_native/table.h
TYPES: dict[str, tuple[int, int]] = {
    "uint8_t": (1, 1),
    "uint8_t_mavlink_version": (1, 1),
    "int8_t": (2, 1),
    "uint16_t": (3, 2),
    "int16_t": (4, 2),
    "uint32_t": (5, 4),
    "int32_t": (6, 4),
    "uint64_t": (7, 8),
    "int64_t": (8, 8),
    "float": (9, 4),
    "double": (10, 8),
    "char": (11, 1),
}
ARRAY = 0x80
MAX_PAYLOAD = 255  # bytes: MAVLink 2's length field is one byte


def _fields(md: MessageDef) -> tuple[list[bytes], bool]:
    """The field entries of `md`'s table entry, and whether C can take them: every field's count and
    offset and its JSON key fit a byte, no name twice, the fields end to end to the message's length, and
    that length a payload's (at most 255 bytes)."""
    fields: list[bytes] = []
    offset = 0
    fits = md.length <= MAX_PAYLOAD
    names: set[str] = set()
    for f in md.fields:
        code, size = TYPES[f.type]
        if f.type == "char":
            count = max(f.array_length, 1)
        elif f.array_length:
            count = f.array_length
            code |= ARRAY
        else:
            count = 1
        key = orjson.dumps(f.name) + b":"
        if count > 255 or offset > 255 or len(key) > 255 or f.name in names:
            fits = False
        names.add(f.name)
        fields.append(struct.pack("<BBBB", code, count & 0xFF, offset & 0xFF, len(key) & 0xFF) + key)
        offset += size * count
    return fields, fits and offset == md.length


def python_only(md: MessageDef) -> bool:
    """Whether frames of `md` go to the Python path, whatever engine runs: its layout cannot be described
    to C (`_fields`). A message over 255 bytes is one: pymavlink takes such a layout (mavparse checks no
    length) and decodes a frame of it as any, its payload (at most 255 bytes on the wire) padded with
    zeros, which is what the Python path does; no frame can carry the whole of it. Every table built on
    the layout table (the native summary's, mavscope.native.summary) marks the same messages."""
    return not _fields(md)[1]


def message_entry(md: MessageDef) -> bytes:
    """One message of the table: header, name, fields (see table.h for the layout)."""
    fields, fits = _fields(md)
    if not fits:
        fields = []  # cannot be described to C (never in a real dialect): Python decodes it
    name = orjson.dumps(md.name)
    head = struct.pack("<IBBBBHH", md.id, md.crc_extra, md.length & 0xFF, min(md.base_length, md.length) & 0xFF,
                       int(not fits), len(fields), len(name))
    return head + name + b"".join(fields)


def build_table(dialect: Dialect) -> bytes:
    """The layouts of every message of `dialect` as the native table blob (wire order, padded offsets)."""
    entries = [message_entry(md) for md in sorted(dialect.messages.values(), key=lambda m: m.id)]
    return TABLE_MAGIC + struct.pack("<II", TABLE_VERSION, len(entries)) + b"".join(entries)
