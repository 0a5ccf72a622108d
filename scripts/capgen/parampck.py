"""An encoder of ArduPilot's packed parameter file (`@PARAM/param.pck`), written from ArduPilot's
libraries/AP_Filesystem/README.md and AP_Filesystem_Param.cpp (`pack_param`), independently of mavscope:

    header: uint16 magic (0x671b), uint16 num_params, uint16 total_params      (little-endian)
    per parameter: [zero pad bytes] type (low nibble: 1 int8, 2 int16, 3 int32, 4 float) | flags << 4,
                   common_len (name bytes shared with the previous name) | (name_len - 1) << 4,
                   name[name_len], value

A value of more than one byte must not cross a block boundary of the FTP read size: when the end of the
block (from the start of the file) would fall inside the value, ArduPilot writes zero pad bytes first.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence

MAGIC = 0x671B
FORMATS = {1: "<b", 2: "<h", 3: "<i", 4: "<f"}
MAV_PARAM_TYPES = {1: 2, 2: 4, 3: 6, 4: 9}  # AP type -> MAV_PARAM_TYPE (INT8, INT16, INT32, REAL32)

Param = tuple[str, int, float]  # name, AP type, value


def _name(raw: bytes, last: bytes) -> tuple[int, bytes]:
    """(bytes shared with the previous name, the bytes sent): at least one byte is sent."""
    common = 0
    while common < min(len(raw), len(last)) and raw[common] == last[common]:
        common += 1
    if common == len(raw):  # AP_Filesystem_Param::pack_param
        common -= 1
    return common, raw[common:]


def pack(params: Sequence[Param], read_size: int) -> bytes:
    """The param.pck a server sends to a client reading `read_size` bytes at a time."""
    out = bytearray(struct.pack("<HHH", MAGIC, len(params), len(params)))
    last = b""
    for name, ptype, value in params:
        raw = name.encode("ascii")
        common, rest = _name(raw, last)
        size = struct.calcsize(FORMATS[ptype])
        packed = 2 + len(rest) + size
        if size > 1:
            mod = (len(out) + packed) % read_size
            if 0 < mod < size:
                out += bytes(size - mod)
        out += bytes([ptype, common | (len(rest) - 1) << 4]) + rest
        out += struct.pack(FORMATS[ptype], int(value) if ptype != 4 else value)
        last = raw
    return bytes(out)


def pack_upload(params: Sequence[Param]) -> bytes:
    """A param.pck as a client uploads it to set parameters (AP_Filesystem_Param::param_upload_parse): no
    padding, no flags, and the header's total_params holds the file's length."""
    body = bytearray()
    last = b""
    for name, ptype, value in params:
        raw = name.encode("ascii")
        common, rest = _name(raw, last)
        body += bytes([ptype, common | (len(rest) - 1) << 4]) + rest
        body += struct.pack(FORMATS[ptype], int(value) if ptype != 4 else value)
        last = raw
    return struct.pack("<HHH", MAGIC, len(params), 6 + len(body)) + bytes(body)


def float32(value: float) -> float:
    """`value` as a float32 holds it (what a decoder reads back)."""
    return struct.unpack("<f", struct.pack("<f", value))[0]
