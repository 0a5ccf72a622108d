"""A PNG file written with the standard library (zlib and struct): the signature, IHDR, one IDAT and IEND,
each chunk with its CRC-32 (PNG specification, ISO/IEC 15948). Scanlines use filter type 0 (none)."""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterable

SIGNATURE = b"\x89PNG\r\n\x1a\n"
GRAY, RGB = 0, 2  # IHDR colour types
CHANNELS = {GRAY: 1, RGB: 3}
LEVEL = 6  # zlib's default compression


def _chunk(tag: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body))


def encode_png(width: int, height: int, rows: Iterable[bytes], color: int = GRAY, depth: int = 8) -> bytes:
    """A PNG of `height` rows of `width` pixels: `rows` are the scanlines' bytes (16-bit samples big-endian,
    as PNG stores them), each width x channels x depth / 8 bytes long."""
    if not (0 < width < 1 << 31 and 0 < height < 1 << 31) or color not in CHANNELS or depth not in (8, 16):
        raise ValueError("not a PNG geometry")
    size = width * CHANNELS[color] * depth // 8
    z = zlib.compressobj(LEVEL)
    parts = []
    count = 0
    for row in rows:
        if len(row) != size:
            raise ValueError("scanline of the wrong length")
        parts.append(z.compress(b"\x00" + row))
        count += 1
    if count != height:
        raise ValueError("wrong number of scanlines")
    parts.append(z.flush())
    header = struct.pack(">IIBBBBB", width, height, depth, color, 0, 0, 0)
    return SIGNATURE + _chunk(b"IHDR", header) + _chunk(b"IDAT", b"".join(parts)) + _chunk(b"IEND", b"")
