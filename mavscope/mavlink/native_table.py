"""The message layouts as the byte string the C extension's `Table` takes (src/mavscope_native/table.h).

Compiled from mavscope's MessageDef/FieldDef, so from pymavlink's parser: never written by hand. Both the
native `read` path (mavscope.native) and the export's native batch source (mavscope.export.native) hand it
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


def message_entry(md: MessageDef) -> bytes:
    """One message of the table: header, name, fields (see table.h for the layout)."""
    fields: list[bytes] = []
    offset = 0
    python_only = False
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
            python_only = True  # cannot be described to C (never in a real dialect): Python decodes it
        names.add(f.name)
        fields.append(struct.pack("<BBBB", code, count & 0xFF, offset & 0xFF, len(key) & 0xFF) + key)
        offset += size * count
    if offset != md.length or md.length > 255:
        python_only = True
    if python_only:
        fields = []
    name = orjson.dumps(md.name)
    head = struct.pack("<IBBBBHH", md.id, md.crc_extra, md.length & 0xFF, min(md.base_length, md.length) & 0xFF,
                       int(python_only), len(fields), len(name))
    return head + name + b"".join(fields)


def build_table(dialect: Dialect) -> bytes:
    """The layouts of every message of `dialect` as the native table blob (wire order, padded offsets)."""
    entries = [message_entry(md) for md in sorted(dialect.messages.values(), key=lambda m: m.id)]
    return TABLE_MAGIC + struct.pack("<II", TABLE_VERSION, len(entries)) + b"".join(entries)
