"""ArduPilot's packed parameter file, `@PARAM/param.pck`, read over MAVLink FTP.

The format, as ArduPilot's libraries/AP_Filesystem/README.md documents it and MAVProxy's
`MAVProxy/modules/lib/param_ftp.py` (now also pymavlink's `mavftp.MAVFTP.ftp_param_decode`) reads it:

- a 6-byte little-endian header: magic (0x671b; 0x671c when the file carries default values, asked for
  with `?withdefaults=1`), num_params (in this file), total_params (on the vehicle);
- then one block per parameter, after any number of zero pad bytes (the server pads so that no value
  crosses a transfer block boundary): a byte with the type in its low nibble (1 int8, 2 int16, 3 int32,
  4 float) and flags in its high nibble (bit 0: a default value follows, only with magic 0x671c); a
  byte with the number of name bytes shared with the previous name in its low nibble and the number of
  new name bytes minus one in its high nibble; the new name bytes; the value (1, 2, 4 or 4 bytes,
  little-endian); the default value, when flagged, in the same type.

Decoding never raises: a block it cannot read ends the decode with a problem (and its offset); the
parameters before it are kept. A count that differs from the header is reported, not refused (MAVProxy
refuses such a file; ArduPilot's header is taken when the file is opened, and parameters can appear in
between). A name ends at its first NUL, as every MAVLink string does (`char_text`: the name a PARAM_SET or
PARAM_VALUE of it would carry); bytes after it are a problem of the decode.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

from mavscope.mavlink.dialect import char_tail, char_text

MAGIC = 0x671B
MAGIC_DEFAULTS = 0x671C
# AP_Param types in the file -> (bytes, struct format, MAV_PARAM_TYPE)
TYPES = {1: (1, "<b", 2), 2: (2, "<h", 4), 3: (4, "<i", 6), 4: (4, "<f", 9)}
MAX_NAME = 16


class PckParam(NamedTuple):
    name: str
    ap_type: int  # 1 int8, 2 int16, 3 int32, 4 float
    value: int | float
    default: int | float | None  # with magic 0x671c: the default (the value itself when not flagged)

    @property
    def mav_type(self) -> int:
        """The MAV_PARAM_TYPE ArduPilot reports for this type (INT8, INT16, INT32, REAL32)."""
        return TYPES[self.ap_type][2]


class PckFile(NamedTuple):
    magic: int | None
    num_params: int | None
    total_params: int | None
    params: tuple[PckParam, ...]
    problems: tuple[str, ...]

    @property
    def with_defaults(self) -> bool:
        return self.magic == MAGIC_DEFAULTS


def is_param_pck(path: str | None) -> bool:
    """Whether an FTP path names the packed parameter file (with or without a query string)."""
    return path is not None and path.split("?", 1)[0].lstrip("/") == "@PARAM/param.pck"


def decode(data: bytes) -> PckFile:
    """The parameters of a param.pck file."""
    if len(data) < 6:
        return PckFile(None, None, None, (), (f"{len(data)} bytes: shorter than the 6-byte header",))
    magic, num, total = struct.unpack_from("<HHH", data, 0)
    if magic not in (MAGIC, MAGIC_DEFAULTS):
        return PckFile(magic, num, total, (), (f"magic 0x{magic:04x} is neither 0x671b nor 0x671c",))
    with_defaults = magic == MAGIC_DEFAULTS
    params: list[PckParam] = []
    problems: list[str] = []
    last = b""
    pos, end = 6, len(data)
    while True:
        while pos < end and data[pos] == 0:
            pos += 1
        if pos >= end:
            break
        if pos + 2 > end:
            problems.append(f"offset {pos}: a truncated block header")
            break
        type_byte, len_byte = data[pos], data[pos + 1]
        ap_type, flags = type_byte & 0x0F, type_byte >> 4
        if ap_type not in TYPES:
            problems.append(f"offset {pos}: unknown parameter type {ap_type}")
            break
        size, fmt, _mav = TYPES[ap_type]
        has_default = with_defaults and bool(flags & 1)
        name_len, common = (len_byte >> 4) + 1, len_byte & 0x0F
        if common > len(last):
            problems.append(f"offset {pos}: {common} name bytes shared with a previous name of {len(last)}")
            break
        stop = pos + 2 + name_len + size * (2 if has_default else 1)
        if stop > end:
            problems.append(f"offset {pos}: a block cut short by the end of the file")
            break
        raw_name = last[:common] + data[pos + 2 : pos + 2 + name_len]
        if len(raw_name) > MAX_NAME:
            problems.append(f"offset {pos}: a name of {len(raw_name)} bytes (at most {MAX_NAME})")
            break
        v_at = pos + 2 + name_len
        value = struct.unpack_from(fmt, data, v_at)[0]
        default = struct.unpack_from(fmt, data, v_at + size)[0] if has_default else (value if with_defaults else None)
        tail = char_tail(raw_name)
        if tail:
            problems.append(f"offset {pos}: the name {char_text(raw_name)!r} has {tail} byte{'s' if tail > 1 else ''} "
                            "after a NUL, which ends it (as a char[16] param_id ends)")
        params.append(PckParam(char_text(raw_name), ap_type, value, default))
        last = raw_name
        pos = stop
    if num != len(params) and not problems:
        problems.append(f"the header says {num} parameters, the file holds {len(params)}")
    return PckFile(magic, num, total, tuple(params), tuple(problems))
