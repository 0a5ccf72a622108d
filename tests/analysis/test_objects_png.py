"""Images sent over MAVLink (DATA_TRANSMISSION_HANDSHAKE + ENCAPSULATED_DATA) are written as PNG too
(issue 35, item 15): raw formats (RAW8U, RAW32U), PGM and BMP get a PNG beside the file as it came; JPEG
and PNG streams are written as they came, their signature checked; a truncated image is written with its
missing rows as zeros, and said (`image-incomplete`, the count of missing packets).

Expected answers, read without mavscope:
- the images' bytes: pymavlink's ENCAPSULATED_DATA packets placed at seqnr x payload, zeros where one is
  missing, cut at the handshake's size (the image transmission protocol, mavlink.io; tests/support/real_truth.py);
- the PNG: decoded by `decode_png` below (PNG specification: chunks with CRC-32, zlib, the five scanline
  filters), and by Pillow where the venv has it;
- the format: MAVLINK_DATA_STREAM_TYPE is JPEG 0, BMP 1, RAW8U 2, RAW32U 3, PGM 4, PNG 5 in common.xml;
  C headers generated before the entries had values number them from 1 (JPEG 1 ... PNG 6: the enum as
  mavgen wrote it then, e.g. ArduPilot's and PX4's old v1.0 headers), which PX4FLOW's firmware was built
  with: its `mavlink_msg_data_transmission_handshake_send(..., MAVLINK_DATA_STREAM_IMG_RAW8U, image_size,
  width, height, image_size / 253 + 1, 253, 100)` sends type 3 with size = width x height, one byte a pixel;
- RAW32U: one little-endian uint32 a pixel; PNG has no 32-bit sample, so 16-bit gray, v >> 8k for the
  fewest whole bytes k that make the largest value fit 16 bits.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import all as v2

from tests.conftest import Cli
from tests.support import flows
from tests.support.pymavlink_reader import read

PX4FLOW = "px4flow_v1_encapsulated_data.tlog"
PURE = {"MAVSCOPE_PURE": "1"}


def decode_png(data: bytes) -> tuple[tuple[int, int, int, int], bytes]:
    """((width, height, bit depth, colour type), the pixels' bytes row after row) of a non-interlaced PNG."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    o, idat, ihdr, tags = 8, b"", None, []
    while o < len(data):
        (n,) = struct.unpack_from(">I", data, o)
        tag, body = data[o + 4:o + 8], data[o + 8:o + 8 + n]
        assert struct.unpack_from(">I", data, o + 8 + n)[0] == zlib.crc32(tag + body), tag
        tags.append(tag)
        if tag == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif tag == b"IDAT":
            idat += body
        o += 12 + n
    assert tags[0] == b"IHDR" and tags[-1] == b"IEND" and ihdr is not None
    w, h, depth, color, _, _, interlace = ihdr
    assert interlace == 0
    bpp = {0: 1, 2: 3, 4: 2, 6: 4}[color] * depth // 8
    stride = w * bpp
    raw = zlib.decompress(idat)
    assert len(raw) == h * (stride + 1)
    rows, prev = [], bytearray(stride)
    for y in range(h):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b, c = prev[x], prev[x - bpp] if x >= bpp else 0
            if kind == 1:
                line[x] = (line[x] + a) & 255
            elif kind == 2:
                line[x] = (line[x] + b) & 255
            elif kind == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return (w, h, depth, color), b"".join(rows)


def pillow_pixels(path: Path) -> tuple[str, bytes] | None:
    try:
        from PIL import Image
    except ImportError:
        return None
    with Image.open(path) as im:
        if im.mode == "I;16":
            return im.mode, im.tobytes("raw", "I;16B")
        return im.mode, im.tobytes()


def _images(msgs: list) -> list[dict]:  # type: ignore[type-arg]
    """Each handshake's image: its fields and its bytes from the ENCAPSULATED_DATA after it (see above)."""
    out: list[dict] = []  # type: ignore[type-arg]
    for m in msgs:
        if m.name == "DATA_TRANSMISSION_HANDSHAKE" and m.msg.size:
            out.append({"hs": m.msg, "got": {}})
        elif m.name == "ENCAPSULATED_DATA" and out:
            out[-1]["got"].setdefault(m.msg.seqnr, bytes(m.msg.data))
    for img in out:
        hs = img["hs"]
        img["data"] = b"".join(img["got"].get(i, bytes(hs.payload))[:hs.payload]
                               for i in range(hs.packets))[:hs.size]
        img["missing"] = [i for i in range(hs.packets) if i not in img["got"]]
    return out


def test_px4flow_images_as_png(cli: Cli, real_captures: Path, tmp_path: Path) -> None:
    path = real_captures / PX4FLOW
    images = _images(read(path))
    assert len(images) == 177
    hs = images[0]["hs"]
    # type 3 (RAW32U in common.xml, RAW8U numbered from 1); 4096 bytes = 64 x 64: one byte a pixel
    assert {(i["hs"].type, i["hs"].size, i["hs"].width, i["hs"].height) for i in images} == {(3, 4096, 64, 64)}
    assert hs.size == hs.width * hs.height
    status, out, err = cli("objects", path, "--out", tmp_path / "a")
    assert status == 0
    assert cli("objects", path, "--out", tmp_path / "b", environ=PURE)[0] == 0
    doc = cli.json("objects", path, "--out", tmp_path / "c")
    objs = doc["objects"]
    assert len(objs) == len(images)
    for o, img in zip(objs, images, strict=True):
        assert o["details"]["format"] == "raw8u" and o["details"]["numbering"] == "from 1"
        assert o["file"].endswith(".raw8u") and o["png"] == o["file"][:-len(".raw8u")] + ".png"
        raw = (tmp_path / "c" / o["file"]).read_bytes()
        assert raw == img["data"]
        png = (tmp_path / "c" / o["png"]).read_bytes()
        assert decode_png(png) == ((64, 64, 8, 0), img["data"])  # 8-bit grayscale, byte for byte
        assert (tmp_path / "a" / o["png"]).read_bytes() == (tmp_path / "b" / o["png"]).read_bytes() == png
    pil = pillow_pixels(tmp_path / "c" / objs[0]["png"])
    assert pil is None or pil == ("L", images[0]["data"])
    # the two truncated images: 7 and 8 packets missing; rows of the missing bytes [first x 253, ...)
    cut = [(n, i) for n, i in enumerate(images, start=1) if i["missing"]]
    assert [(n, len(i["missing"])) for n, i in cut] == [(1, 7), (177, 8)]
    (incomplete,) = [f for f in doc["findings"] if f["code"] == "image-incomplete"]
    for n, i in cut:
        first, end = i["missing"][0] * 253, min(4096, (i["missing"][-1] + 1) * 253)
        rows = f"rows {first // 64}-{(end - 1) // 64} of 64"
        assert f"image {n} (64 x 64 RAW8U): {len(i['missing'])} of 17 packets missing, {rows}" in incomplete["message"]
    (fmt,) = [f for f in doc["findings"] if f["code"] == "image-format"]
    assert fmt["message"].startswith("177 image(s) from 81/50") and "numbered MAVLINK_DATA_STREAM_TYPE from 1" in \
        fmt["message"]
    assert "Written to" in out and "0001-image_1.raw8u + 0001-image_1.png" in out


def _tlog(tmp_path: Path, name: str, kind: int, data: bytes, width: int, height: int,
          lose: frozenset[int] = frozenset(), payload: int = 253) -> str:
    """A camera 1/100 sending one image: its handshake and the packets not in `lose`."""
    cam = flows.Sender(1, 100)
    packets = (len(data) + payload - 1) // payload
    entries = [(flows.T0, cam.pack(v2.MAVLink_data_transmission_handshake_message(
        kind, len(data), width, height, packets, payload, 80)))]
    for i in range(packets):
        chunk = data[i * payload:(i + 1) * payload].ljust(253, b"\0")
        if i not in lose:
            entries.append((flows.T0 + 0.01 * (i + 1), cam.pack(v2.MAVLink_encapsulated_data_message(i, list(chunk)))))
    entries.append((flows.T0 + 1, cam.pack(flows.heartbeat())))
    return flows.write_tlog(tmp_path, entries, name)


def _one(cli: Cli, tmp_path: Path, capture: str) -> tuple[dict, dict, Path]:  # type: ignore[type-arg]
    out = tmp_path / Path(capture).stem
    doc = cli.json("objects", capture, "--out", out)
    assert doc == cli.json("objects", capture, "--out", out, environ=PURE)
    (obj,) = doc["objects"]
    return doc, obj, out


def test_raw8u_truncated(cli: Cli, tmp_path: Path) -> None:
    # 20 x 30 = 600 bytes in 3 packets of 253; packet 1 (bytes 253-505: rows 12-25) never arrives
    pixels = bytes((x * 7 + y * 3) % 256 for y in range(30) for x in range(20))
    doc, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "raw8.tlog", 2, pixels, 20, 30, frozenset({1})))
    expected = pixels[:253] + bytes(253) + pixels[506:]
    assert (obj["details"]["format"], obj["details"]["numbering"]) == ("raw8u", "common.xml")
    assert (out / obj["file"]).read_bytes() == expected
    assert decode_png((out / obj["png"]).read_bytes()) == ((20, 30, 8, 0), expected)
    assert obj["details"]["missing_rows"] == [[12, 25]]
    (f,) = [f for f in doc["findings"] if f["code"] == "image-incomplete"]
    assert "image 1 (20 x 30 RAW8U): 1 of 3 packets missing, rows 12-25 of 30 are zeros in its PNG" in f["message"]
    assert not [f for f in doc["findings"] if f["code"] == "image-format"]


def test_raw32u_as_16_bit(cli: Cli, tmp_path: Path) -> None:
    values = [0, 1, 1000, 70000, 2**32 - 1, 123456789, 5, 9, 65536, 42, 7, 3]  # 4 x 3 pixels
    data = struct.pack("<12I", *values)
    _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "raw32.tlog", 3, data, 4, 3))
    assert (obj["details"]["format"], obj["file"][-7:]) == ("raw32u", ".raw32u")
    # the largest, 2**32 - 1, needs 32 bits: every value shifted right by 16 (two whole bytes)
    expected = struct.pack(">12H", *(v >> 16 for v in values))
    assert decode_png((out / obj["png"]).read_bytes()) == ((4, 3, 16, 0), expected)
    # values below 2**24 (the top byte unused): shifted by 8; below 65536: as they are
    for vals, shift in (([0, 1, 1000, 70000, 2**24 - 1, 5], 8), ([0, 1, 65535, 300, 9, 2], 0)):
        _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, f"raw32_{shift}.tlog", 3, struct.pack("<6I", *vals), 3, 2))
        expected = struct.pack(">6H", *(v >> shift for v in vals))
        assert decode_png((out / obj["png"]).read_bytes()) == ((3, 2, 16, 0), expected)


def test_jpeg_and_png_streams_are_written_as_they_came(cli: Cli, tmp_path: Path) -> None:
    jpeg = b"\xff\xd8\xff\xe0\x00\x10JFIF\x00" + bytes(range(200)) + b"\xff\xd9"
    _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "j.tlog", 0, jpeg, 16, 16))
    assert (obj["details"]["format"], obj["details"]["signature"], obj["png"]) == ("jpeg", "ok", None)
    assert obj["file"].endswith(".jpg") and (out / obj["file"]).read_bytes() == jpeg
    assert sorted(p.name for p in out.iterdir()) == sorted([obj["file"], "manifest.json"])
    # type 0 without JPEG's signature: said, no PNG, the bytes kept as they came
    doc, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "notjpeg.tlog", 0, b"GIF89a" + bytes(100), 16, 16))
    assert (obj["details"]["format"], obj["details"]["signature"]) == ("unknown", "absent")
    assert "no JPEG signature" in obj["details"]["format_problem"]
    assert any(f["code"] == "image-format" for f in doc["findings"])
    # a PNG stream (type 5), built here by hand: written as it came, nothing converted
    row = b"\x00" + bytes([10, 20, 30])
    body = struct.pack(">IIBBBBB", 3, 1, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + b"".join(
        struct.pack(">I", len(b)) + t + b + struct.pack(">I", zlib.crc32(t + b))
        for t, b in ((b"IHDR", body), (b"IDAT", zlib.compress(row)), (b"IEND", b"")))
    _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "p.tlog", 5, png, 3, 1))
    assert (obj["details"]["format"], obj["png"], obj["file"][-4:]) == ("png", None, ".png")
    assert (out / obj["file"]).read_bytes() == png


def test_pgm_and_bmp(cli: Cli, tmp_path: Path) -> None:
    pgm = b"P5\n# a comment\n4 2\n15\n" + bytes([0, 5, 10, 15, 15, 10, 5, 0])
    _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "g.tlog", 4, pgm, 4, 2))
    assert obj["details"]["format"] == "pgm"
    assert decode_png((out / obj["png"]).read_bytes()) == ((4, 2, 8, 0), bytes(v * 255 // 15 for v in pgm[-8:]))
    # a 3 x 2 24-bit BMP, rows bottom-up, each padded to 12 bytes; pixels (B, G, R) as written
    bottom = [(1, 2, 3), (4, 5, 6), (7, 8, 9)]
    top = [(10, 11, 12), (13, 14, 15), (16, 17, 18)]
    pixels = b"".join(bytes(sum(r, ())) + b"\0\0\0" for r in (bottom, top))
    info = struct.pack("<IiiHHIIiiII", 40, 3, 2, 1, 24, 0, len(pixels), 2835, 2835, 0, 0)
    bmp = b"BM" + struct.pack("<IHHI", 54 + len(pixels), 0, 0, 54) + info + pixels
    _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "b.tlog", 1, bmp, 3, 2))
    assert obj["details"]["format"] == "bmp"
    rgb = b"".join(bytes((r, g, b)) for b, g, r in top + bottom)  # top row first, RGB
    assert decode_png((out / obj["png"]).read_bytes()) == ((3, 2, 8, 2), rgb)


def test_size_that_fits_no_geometry(cli: Cli, tmp_path: Path) -> None:
    """A RAW8U handshake whose size is not width x height (nor x 4): no PNG, said; the bytes written."""
    doc, obj, out = _one(cli, tmp_path, _tlog(tmp_path, "odd.tlog", 2, bytes(range(250)), 60000, 60000))
    assert obj["details"]["format"] == "unknown" and obj["png"] is None
    assert (out / obj["file"]).read_bytes() == bytes(range(250))


@pytest.mark.parametrize("kind", [1, 4])
def test_a_header_declaring_more_than_it_holds(cli: Cli, tmp_path: Path, kind: int) -> None:
    """A BMP or PGM header of 65535 x 65535 pixels over 300 bytes: no PNG (bounded work), why said."""
    head = (b"P5 65535 65535 255\n" if kind == 4 else
            b"BM" + struct.pack("<IHHI", 0, 0, 0, 54) + struct.pack("<IiiHHI", 40, 65535, 65535, 1, 24, 0))
    _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, f"big{kind}.tlog", kind, head.ljust(300, b"\0"), 8, 8))
    assert obj["png"] is None and "more than its 300 bytes hold" in obj["png_not_written"]


@pytest.mark.parametrize("mode", ["P", "L", "RGB", "RGBA"])
def test_bmp_files_pillow_writes(cli: Cli, tmp_path: Path, mode: str) -> None:
    """BMPs as another program writes them (Pillow: an 8-bit palette for P and L, 24 and 32 bits), sent as
    type 1: the PNG holds the pixels Pillow reads from the BMP, as RGB."""
    pil = pytest.importorskip("PIL.Image")
    import io

    im = pil.new("RGB", (5, 3))
    im.putdata([(i * 10, i * 20 % 256, 255 - i * 15) for i in range(15)])
    im = im.convert(mode)
    buf = io.BytesIO()
    im.save(buf, "BMP")
    _, obj, out = _one(cli, tmp_path, _tlog(tmp_path, f"{mode}.tlog", 1, buf.getvalue(), 5, 3))
    with pil.open(io.BytesIO(buf.getvalue())) as back:
        want = back.convert("RGB").tobytes()
    assert decode_png((out / obj["png"]).read_bytes()) == ((5, 3, 8, 2), want)
