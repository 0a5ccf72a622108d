"""How an image sent over MAVLink reads, and the PNG any image viewer opens.

The handshake's `type` is a MAVLINK_DATA_STREAM_TYPE. common.xml numbers it JPEG 0, BMP 1, RAW8U 2,
RAW32U 3, PGM 4, PNG 5; before common.xml gave the entries values, mavgen numbered them from 1 (JPEG 1 ...
PNG 6), and C code generated then sends those numbers: PX4FLOW's firmware announces its 8-bit camera image,
MAVLINK_DATA_STREAM_IMG_RAW8U, as type 3 (RAW32U today) with size = width x height. So the bytes decide
where they can (`read_image`): JPEG, PNG, BMP and PGM files start with their signature; a raw image is
width x height bytes (RAW8U: 8-bit grayscale, row after row, as QGroundControl's ImageProtocolManager shows
it: a PGM of those bytes, maxval 255) or 4 bytes a pixel (RAW32U: a 32-bit unsigned value per pixel,
little-endian as MAVLink's fields). The reading says which numbering names the format it found, and what
contradicts the type (`problem`).

`image_png(details, data)`: the PNG of a raw, BMP or PGM image (JPEG and PNG streams are written as they
came): RAW8U as 8-bit grayscale, byte for byte; RAW32U as 16-bit grayscale, each value shifted right by the
fewest whole bytes that make the largest fit (PNG holds no 32-bit sample); PGM (P5) as 8-bit grayscale
(maxval < 256, scaled to 0..255 where maxval is not 255) or 16-bit (samples as they are); BMP
(uncompressed: 8-bit palette, 24 and 32 bits) as RGB. No step loops per pixel in Python. Bytes never
received are zeros in the object, so a missing packet's rows are zero rows in the PNG (`missing_rows` lists
a raw image's). The work is bounded by the object's size: a header declaring more pixels than the image's
bytes hold makes no PNG.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

from mavscope.analysis.objects.png import GRAY, RGB, SIGNATURE, encode_png

COMMON = {0: "jpeg", 1: "bmp", 2: "raw8u", 3: "raw32u", 4: "pgm", 5: "png"}  # common.xml's values
FROM_ONE = {k + 1: v for k, v in COMMON.items()}  # mavgen's numbering before the entries had values
LABEL = {"jpeg": "JPEG", "bmp": "BMP", "raw8u": "RAW8U", "raw32u": "RAW32U", "pgm": "PGM", "png": "PNG"}
EXTENSION = {"jpeg": ".jpg", "bmp": ".bmp", "raw8u": ".raw8u", "raw32u": ".raw32u", "pgm": ".pgm", "png": ".png"}
RAW = ("raw8u", "raw32u")
CONVERTED = ("raw8u", "raw32u", "pgm", "bmp")  # formats written as a PNG too
HEAD = 64  # bytes of an image's start its signature is looked for in
MAX_SIDE = 65535  # pixels a side of a BMP or PGM converted (a handshake's uint16 width and height)
_WS = b" \t\n\r\x0b\x0c"


@dataclass(frozen=True, slots=True)
class ImageReading:
    format: str  # jpeg, bmp, raw8u, raw32u, pgm, png; "unknown" where nothing fits
    numbering: str  # "common.xml", "from 1" (the older numbering), "" (the type names another format)
    signature: str  # "ok", "absent" (a file format without its signature), "unchecked" (first bytes
    # never received), "none" (raw images have none)
    problem: str  # what contradicts the type ("" where nothing does)


def signature_of(head: bytes) -> str | None:
    """The file format whose signature `head` starts with."""
    if head.startswith(b"\xff\xd8\xff"):
        return "jpeg"
    if head.startswith(SIGNATURE):
        return "png"
    if head.startswith(b"BM") and len(head) >= 18:
        return "bmp"
    if head[:2] == b"P5" and head[2:3] and head[2] in _WS:
        return "pgm"
    return None


def _raw_by_size(width: int, height: int, size: int) -> str | None:
    pixels = width * height
    if pixels and size == pixels:
        return "raw8u"
    if pixels and size == 4 * pixels:
        return "raw32u"
    return None


def _named(t: int) -> str:
    names = [f"{LABEL[f]} in {where}" for f, where in ((COMMON.get(t), "common.xml"), (FROM_ONE.get(t), "the "
             "numbering from 1")) if f is not None]
    return " and ".join(names) or "no format in either numbering"


def read_image(t: int, width: int, height: int, size: int, head: bytes, head_received: bool) -> ImageReading:
    """How an image of type `t`, `width` x `height`, `size` bytes starting with `head` reads
    (`head_received`: its first bytes are in the capture)."""
    named = {f for f in (COMMON.get(t), FROM_ONE.get(t)) if f is not None}
    raw = _raw_by_size(width, height, size)
    fits_raw = raw is not None and (raw in named or not named)
    sig = signature_of(head) if head_received else None
    if sig is not None:
        fmt, state = sig, "ok"
        why = f"its bytes start with {LABEL[sig]}'s signature"
    elif fits_raw:
        fmt, state = raw, "none"  # type: ignore[assignment]  # (raw is not None)
        why = f"its {size:,} bytes are {width} x {height}{' x 4' if raw == 'raw32u' else ''}"
    elif not head_received and COMMON.get(t) is not None and COMMON[t] not in RAW:
        fmt, state, why = COMMON[t], "unchecked", ""
    else:
        files = sorted(LABEL[f] for f in named if f not in RAW)
        what = f"start with no {' or '.join(files)} signature" if files and head_received else (
            "start with no signature" if head_received else "were not received at its start")
        return ImageReading("unknown", "", "absent" if head_received else "unchecked",
                            f"type {t} names {_named(t)}, but its bytes {what} and its {size:,} bytes are not "
                            f"{width} x {height} (x 4): written as received, no PNG")
    if COMMON.get(t) == fmt:
        return ImageReading(fmt, "common.xml", state, "")
    if FROM_ONE.get(t) == fmt:
        return ImageReading(fmt, "from 1", state,
                            f"type {t} names {_named(t)}; {why}: {LABEL[fmt]}, type {t} as MAVLink numbered "
                            "MAVLINK_DATA_STREAM_TYPE from 1 before common.xml gave it values (PX4FLOW's firmware)")
    return ImageReading(fmt, "", state, f"type {t} names {_named(t)}, but {why}: read as {LABEL[fmt]}")


def missing_rows(fmt: str, width: int, gaps: list[tuple[int, int]]) -> list[list[int]]:
    """The rows ([first, last] runs) of a raw image that bytes never received (`gaps`) fall in."""
    if fmt not in RAW or width <= 0:
        return []
    stride = width * (4 if fmt == "raw32u" else 1)
    runs: list[list[int]] = []
    for a, b in gaps:
        first, last = a // stride, (b - 1) // stride
        if runs and first <= runs[-1][1] + 1:
            runs[-1][1] = max(runs[-1][1], last)
        else:
            runs.append([first, last])
    return runs


class NoPng(Exception):
    """Why an image makes no PNG."""


def image_png(details: Mapping[str, object], data: bytes) -> tuple[bytes, dict[str, object]]:
    """The PNG of an image whose reading (`details`: format, width, height) is a converted format, and what
    it holds (width, height, colour, bit depth, scaling); NoPng says why there is none."""
    fmt = details.get("format")
    width, height = details.get("width"), details.get("height")
    if fmt not in CONVERTED or not isinstance(width, int) or not isinstance(height, int):
        raise NoPng(f"a {LABEL.get(str(fmt), 'unknown')} image is written as it came")
    if fmt == "raw8u":
        return _gray8(width, height, data)
    if fmt == "raw32u":
        return _gray32(width, height, data)
    if fmt == "pgm":
        return _pgm(data)
    return _bmp(data)


def _rows(data: bytes, stride: int, height: int) -> Iterator[bytes]:
    for i in range(height):
        yield data[i * stride:(i + 1) * stride]


def _gray8(width: int, height: int, data: bytes) -> tuple[bytes, dict[str, object]]:
    data = data[:width * height].ljust(width * height, b"\0")
    return encode_png(width, height, _rows(data, width, height)), {
        "width": width, "height": height, "color": "gray", "depth": 8}


def _gray32(width: int, height: int, data: bytes) -> tuple[bytes, dict[str, object]]:
    """16-bit samples of little-endian uint32 values: each shifted right by the fewest whole bytes that make
    the largest fit (values below 65,536 as they are), taken by slicing, so no loop runs per pixel."""
    n = width * height
    data = data[:4 * n].ljust(4 * n, b"\0")
    zero = bytes(n)
    k = 2 if data[3::4] != zero else 1 if data[2::4] != zero else 0
    pixels = bytearray(2 * n)
    pixels[0::2], pixels[1::2] = data[k + 1::4], data[k::4]  # PNG's big-endian samples
    return encode_png(width, height, _rows(bytes(pixels), 2 * width, height), GRAY, 16), {
        "width": width, "height": height, "color": "gray", "depth": 16,
        "scaled": f"each value shifted right by {8 * k} bits (PNG holds no 32-bit sample)"}


def _pgm_header(data: bytes) -> tuple[int, int, int, int]:
    """(width, height, maxval, offset of the pixels) of a binary PGM (P5), comments skipped."""
    fields: list[int] = []
    o = 2
    while len(fields) < 3:
        while o < len(data) and (data[o] in _WS or data[o] == 0x23):
            if data[o] == 0x23:  # a comment, to the end of its line
                end = data.find(b"\n", o)
                o = len(data) if end < 0 else end
            o += 1
        start = o
        while o < len(data) and 0x30 <= data[o] <= 0x39 and o - start < 10:
            o += 1
        if o == start or o >= len(data) or data[o] not in _WS:
            raise NoPng("a PGM header that does not parse")
        fields.append(int(data[start:o]))
    w, h, maxval = fields
    if not (0 < w <= MAX_SIDE and 0 < h <= MAX_SIDE and 0 < maxval < 65536):
        raise NoPng(f"a PGM header of {w} x {h}, maxval {maxval}")
    return w, h, maxval, o + 1


def _pgm(data: bytes) -> tuple[bytes, dict[str, object]]:
    w, h, maxval, o = _pgm_header(data)
    depth = 8 if maxval < 256 else 16
    need = w * h * depth // 8
    if need > len(data) - o:
        raise NoPng(f"its PGM header declares {w} x {h} pixels, more than its {len(data):,} bytes hold")
    pixels = data[o:o + need]
    info: dict[str, object] = {"width": w, "height": h, "color": "gray", "depth": depth}
    if depth == 8 and maxval != 255:
        pixels = pixels.translate(bytes(min(255, v * 255 // maxval) for v in range(256)))
        info["scaled"] = f"0..{maxval} to 0..255"
    elif depth == 16 and maxval != 65535:
        info["scaled"] = f"none: samples as they are, of 0..{maxval}"  # (big-endian in PGM as in PNG)
    return encode_png(w, h, _rows(pixels, w * depth // 8, h), GRAY, depth), info


def _bmp(data: bytes) -> tuple[bytes, dict[str, object]]:
    if len(data) < 26:
        raise NoPng("a BMP shorter than its headers")
    offset, dib = struct.unpack_from("<II", data, 10)
    if dib == 12:
        w, h, _, bpp = struct.unpack_from("<HHHH", data, 18)
        compression, colors, entry = 0, 0, 3
    elif 40 <= dib <= 124 and len(data) >= 14 + 40:
        w, h, _, bpp, compression = struct.unpack_from("<iiHHI", data, 18)
        colors, entry = struct.unpack_from("<I", data, 46)[0], 4
    else:
        raise NoPng(f"a BMP header of {dib} bytes")
    top_down = h < 0
    h = abs(h)
    if not (0 < w <= MAX_SIDE and 0 < h <= MAX_SIDE):
        raise NoPng(f"a BMP of {w} x {h} pixels (at most {MAX_SIDE:,} a side, as a handshake can say)")
    if compression != 0 or bpp not in (8, 24, 32):
        raise NoPng(f"a BMP of {bpp} bits, compression {compression} (uncompressed 8, 24 and 32 bits are converted)")
    stride = (w * bpp + 31) // 32 * 4
    if offset + stride * h > len(data):
        raise NoPng(f"its BMP header declares {w} x {h} pixels, more than its {len(data):,} bytes hold")
    lut: tuple[bytes, bytes, bytes] | None = None
    if bpp == 8:
        n = colors or 256
        start = 14 + dib
        if n > 256 or start + n * entry > offset:
            raise NoPng("a BMP palette that does not fit")
        pal = data[start:start + n * entry]
        pad = bytes(256 - n)
        lut = (pal[2::entry] + pad, pal[1::entry] + pad, pal[0::entry] + pad)

    def rows() -> Iterator[bytes]:
        for i in range(h):
            r = h - 1 - i if not top_down else i
            row = data[offset + r * stride:offset + r * stride + stride]
            out = bytearray(3 * w)
            if lut is not None:
                px = row[:w]
                out[0::3], out[1::3], out[2::3] = px.translate(lut[0]), px.translate(lut[1]), px.translate(lut[2])
            else:
                step = bpp // 8
                out[0::3], out[1::3], out[2::3] = (row[2:w * step:step], row[1:w * step:step], row[0:w * step:step])
            yield bytes(out)

    return encode_png(w, h, rows(), RGB, 8), {"width": w, "height": h, "color": "rgb", "depth": 8}
