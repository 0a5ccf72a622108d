"""Parameter values as the messages carry them, and as text.

PARAM_VALUE and PARAM_SET carry every value in a 4-byte float field, `param_type` (MAV_PARAM_TYPE)
saying what it is. Integers travel one of two ways (https://mavlink.io/en/services/parameter.html,
"Parameter Encoding"): ArduPilot converts them to a float (C cast, MAV_PROTOCOL_CAPABILITY_PARAM_
ENCODE_C_CAST), PX4 puts the integer's bytes in the field (byte-wise, ..._ENCODE_BYTEWISE). The
component's AUTOPILOT_VERSION capabilities say which; else its HEARTBEAT (PX4: byte-wise); else a value
of an integer type whose float is not a whole number can only be byte-wise. PARAM_EXT_* carry the value's
bytes in a 128-byte char array (MAV_PARAM_EXT_TYPE; CUSTOM is text).
"""

from __future__ import annotations

import math
import struct

from mavscope.mavlink.floats import f32_text, f32_value
from mavscope.mavlink.frame import Frame, plaintext_payload

Value = int | float | str
REAL32, REAL64 = 9, 10
EXT_CUSTOM = 11
# MAV_PARAM_TYPE / MAV_PARAM_EXT_TYPE integer types -> struct format of their bytes
INT_FORMATS = {1: "<B", 2: "<b", 3: "<H", 4: "<h", 5: "<I", 6: "<i", 7: "<Q", 8: "<q"}
TYPE_NAMES = {1: "UINT8", 2: "INT8", 3: "UINT16", 4: "INT16", 5: "UINT32", 6: "INT32", 7: "UINT64", 8: "INT64",
              9: "REAL32", 10: "REAL64", 11: "CUSTOM"}
C_CAST, BYTEWISE = "c-cast", "bytewise"


def field_bytes(f: Frame, name: str) -> bytes | None:
    """The raw bytes of field `name` of the frame's payload (zero-filled as a receiver restores them)."""
    md = f.msgdef
    payload = plaintext_payload(f)
    if md is None or payload is None:
        return None
    fd = md.field(name)
    if fd is None:
        return None
    raw = payload[fd.offset : fd.offset + fd.size]
    return raw + bytes(fd.size - len(raw))


def from_float_field(raw: bytes, ptype: int, encoding: str | None) -> tuple[Value, str]:
    """A PARAM_VALUE/PARAM_SET value from the 4 bytes of `param_value`; returns (value, encoding used)."""
    f = struct.unpack("<f", raw)[0]
    fmt = INT_FORMATS.get(ptype)
    if fmt is None or ptype > 6:  # floats, and 64-bit types (which a 4-byte field cannot carry whole)
        return f, encoding or C_CAST
    if encoding is None:
        encoding = C_CAST if math.isfinite(f) and f == int(f) else BYTEWISE
    if encoding == BYTEWISE:
        size = struct.calcsize(fmt)
        return struct.unpack(fmt, raw[:size])[0], encoding
    return (int(f) if math.isfinite(f) else f), encoding


def from_ext_field(raw: bytes, ptype: int) -> Value:
    """A PARAM_EXT_* value from the bytes of its 128-byte `param_value`."""
    fmt = INT_FORMATS.get(ptype)
    if fmt is not None:
        return struct.unpack_from(fmt, raw)[0]
    if ptype == REAL32:
        return struct.unpack_from("<f", raw)[0]
    if ptype == REAL64:
        return struct.unpack_from("<d", raw)[0]
    return raw.split(b"\0", 1)[0].decode("utf-8", "backslashreplace")


def _f32(v: float) -> bytes | None:
    try:
        return struct.pack("<f", v)
    except (OverflowError, struct.error):
        return None


def same(a: Value | None, b: Value | None) -> bool:
    """Whether two values are the same parameter value: integers equal, floats equal as float32 (so 0.3
    sent as a float and 0.30000001192092896 read back are the same), NaN equal to NaN of the same bits."""
    if a is None or b is None:
        return a is b
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    if isinstance(a, int) and isinstance(b, int):
        return a == b
    fa, fb = _f32(float(a)), _f32(float(b))
    if fa is None or fb is None:
        return float(a) == float(b)
    return fa == fb


def value_text(v: Value | None) -> str:
    """A value as a parameter file writes it: integers as they are, a float as the shortest decimal that
    reads back as the same float32."""
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    if isinstance(v, int):
        return str(v)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    text = f32_text(v)  # (mavlink/floats.py; a double beyond float32's range as repr writes it)
    if "e" in text:  # a parameter file wants plain decimals where they are short enough
        target = _f32(v)
        plain = f"{float(text):.12f}".rstrip("0").rstrip(".")
        if len(plain) <= 20 and _f32(float(plain)) == target:
            text = plain
    elif text.endswith(".0"):  # and whole numbers as integers are written (100, not 100.0)
        text = text[:-2]
    return text


def json_value(v: Value | None) -> object:
    """A value for JSON: floats as the shortest float32 decimal (0.3, not 0.30000001192092896); NaN and
    infinities as text (JSON cannot hold them)."""
    if isinstance(v, float):
        if not math.isfinite(v):
            return value_text(v)
        return f32_value(v)
    return v
