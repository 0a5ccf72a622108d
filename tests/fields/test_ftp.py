"""MAVLink FTP inside FILE_TRANSFER_PROTOCOL: the tree (labels, byte ranges) and the filters, on frames
pymavlink builds (the FTP payloads packed by pymavlink's own `mavftp_op.FTP_OP`), one per opcode group."""

from __future__ import annotations

import json
import struct

import pytest
from pymavlink.mavftp_op import FTP_OP

from mavscope.fields.registry import MISSING, FieldRegistry, field
from mavscope.fields.tree import flatten, frame_items
from mavscope.filter import FilterError, compile_filter
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from tests.conftest import Cli
from tests.fields.support import ftp_frame, item, items_named, wire

# pymavlink's opcodes and errors (pymavlink.mavftp_op, pymavlink.mavftp.FtpError)
OPEN_RO, READ, LIST, RENAME, CRC32, BURST, WRITE, ACK, NAK = 4, 5, 3, 13, 14, 15, 7, 128, 129
ERRORS = ["None", "Fail", "FailErrno", "InvalidDataSize", "InvalidSession", "NoSessionsAvailable", "EOF",
          "UnknownCommand", "FileExists", "FileProtected", "FileNotFound"]


def op(opcode: int, data: bytes = b"", *, seq: int = 1, session: int = 0, req: int = 0, burst: int = 0,
       offset: int = 0, size: int | None = None) -> bytes:
    return bytes(FTP_OP(seq, session, opcode, len(data) if size is None else size, req, burst, offset,
                        bytearray(data)).pack())


def get(frame: Frame, name: str) -> object:
    return field(name).get(frame)


def matches(frames: list[Frame], text: str, dialect: Dialect) -> list[int]:
    flt = compile_filter(text, dialect)
    return [i for i, f in enumerate(frames) if flt.matches(f)]


@pytest.mark.parametrize("version", [1, 2])
def test_path_request_tree(dialect: Dialect, version: int) -> None:
    f = ftp_frame(dialect, op(OPEN_RO, b"@PARAM/param.pck", seq=7, session=2), version)
    payload = item(f, dialect, "FILE_TRANSFER_PROTOCOL.payload")
    assert payload.label.startswith("payload: MAVLink FTP OpenFileRO '@PARAM/param.pck', seq 7, session 2")
    base = (10 if version == 2 else 6) + 3  # header, then target_network/system/component
    assert [(it.name, it.offset, it.length) for it in payload.children[:8]] == [
        ("ftp.seq", base, 2), ("ftp.session", base + 2, 1), ("ftp.opcode", base + 3, 1), ("ftp.size", base + 4, 1),
        ("ftp.req_opcode", base + 5, 1), ("ftp.burst_complete", base + 6, 1), ("ftp.padding", base + 7, 1),
        ("ftp.offset", base + 8, 4)]
    assert [it.label for it in payload.children[:5]] == [
        "Sequence number: 7", "Session: 2", "Opcode: OpenFileRO (4)", "Size: 16", "Request opcode: None (0)"]
    assert wire(f, item(f, dialect, "ftp.seq")) == struct.pack("<H", 7)
    data = item(f, dialect, "ftp.data")
    path = item(f, dialect, "ftp.path")
    assert (data.offset, data.length) == (base + 12, 16)
    assert path.label == "Path: '@PARAM/param.pck'" and path in data.children
    assert wire(f, path) == b"@PARAM/param.pck"
    assert (get(f, "ftp.opcode"), get(f, "ftp.path"), get(f, "ftp.session")) == (4, "@PARAM/param.pck", 2)
    assert get(f, "ftp.error") is MISSING and get(f, "ftp.malformed") is MISSING


def test_rename_two_paths(dialect: Dialect) -> None:
    f = ftp_frame(dialect, op(RENAME, b"/a/old.txt\0/a/new.txt"))
    assert (get(f, "ftp.path"), get(f, "ftp.new_path")) == ("/a/old.txt", "/a/new.txt")
    assert wire(f, item(f, dialect, "ftp.new_path")) == b"/a/new.txt"
    assert "Rename '/a/old.txt' -> '/a/new.txt'" in item(f, dialect, "FILE_TRANSFER_PROTOCOL.payload").label


def test_read_ack_with_data(dialect: Dialect) -> None:
    chunk = bytes(range(1, 81))
    f = ftp_frame(dialect, op(ACK, chunk, seq=12, session=1, req=READ, offset=480))
    data = item(f, dialect, "ftp.data")
    assert data.label == f"Data (80 bytes): {chunk.hex(' ')}"
    assert wire(f, data) == chunk and get(f, "ftp.data") == chunk
    assert "ACK (ReadFile), 80 bytes at offset 480, seq 12, session 1" in item(
        f, dialect, "FILE_TRANSFER_PROTOCOL.payload").label


def test_data_is_size_bytes_only(dialect: Dialect) -> None:
    """Bytes past `size` (stale buffer contents) are no data."""
    f = ftp_frame(dialect, op(ACK, b"abcdefgh", req=READ, size=3))
    assert get(f, "ftp.data") == b"abc" and item(f, dialect, "ftp.data").length == 3


def test_read_request_carries_no_data(dialect: Dialect) -> None:
    f = ftp_frame(dialect, op(BURST, size=239, session=1, offset=4096))
    assert get(f, "ftp.data") is MISSING and not items_named(f, dialect, "ftp.data")
    assert "BurstReadFile, offset 4096, size 239" in item(f, dialect, "FILE_TRANSFER_PROTOCOL.payload").label


def test_burst_read_ack_burst_complete(dialect: Dialect) -> None:
    f = ftp_frame(dialect, op(ACK, b"\xaa" * 239, req=BURST, burst=1, offset=239 * 5))
    assert item(f, dialect, "ftp.burst_complete").label == "Burst complete: 1"
    assert "ACK (BurstReadFile), 239 bytes at offset 1195, burst complete" in item(
        f, dialect, "FILE_TRANSFER_PROTOCOL.payload").label
    assert matches([f], "ftp.req_opcode == BurstReadFile && ftp.burst_complete == 1", dialect) == [0]


@pytest.mark.parametrize("code", range(len(ERRORS)))
def test_nak_each_error(dialect: Dialect, code: int) -> None:
    data = bytes([code, 17]) if code == 2 else bytes([code])
    f = ftp_frame(dialect, op(NAK, data, req=OPEN_RO))
    err = item(f, dialect, "ftp.error")
    if code == 0:  # a zero the v2 sender trimmed
        assert err.label == "Error: None (0) [trimmed: zero-filled]" and wire(f, err) == b""
    else:
        assert err.label == f"Error: {ERRORS[code]} ({code})" and wire(f, err) == bytes([code])
    assert get(f, "ftp.error") == code
    assert matches([f], f"ftp.error == {ERRORS[code]}", dialect) == [0]
    if code == 2:
        assert get(f, "ftp.errno") == 17 and wire(f, item(f, dialect, "ftp.errno")) == bytes([17])
    else:
        assert get(f, "ftp.errno") is MISSING


def test_list_directory_ack_entries(dialect: Dialect) -> None:
    listing = b"Fparam.pck\t1234\0Dlogs\0S\0Fa b.txt\t0\0"
    f = ftp_frame(dialect, op(ACK, listing, req=LIST, offset=2), version=1)  # v1: no trailing NUL trimmed
    entries = items_named(f, dialect, "ftp.entry")
    assert [e.label for e in entries] == ["Entry 1: file 'param.pck', 1234 bytes", "Entry 2: directory 'logs'",
                                         "Entry 3: skipped", "Entry 4: file 'a b.txt', 0 bytes"]
    assert [wire(f, e) for e in entries] == [b"Fparam.pck\t1234\0", b"Dlogs\0", b"S\0", b"Fa b.txt\t0\0"]
    first = {c.name: c for c in entries[0].children}
    assert wire(f, first["ftp.entry.type"]) == b"F" and wire(f, first["ftp.entry.name"]) == b"param.pck"
    assert wire(f, first["ftp.entry.size"]) == b"1234" and first["ftp.entry.size"].value == 1234
    assert get(f, "ftp.entry.name") == ("param.pck", "logs", "a b.txt")
    assert get(f, "ftp.entry.size") == (1234, 0)
    assert get(f, "ftp.entry.type") == ("file", "directory", "skip", "file")
    for text in ('ftp.entry.name == "logs"', "ftp.entry.size > 1000", "ftp.entry.type == directory", "ftp.entry"):
        assert matches([f], text, dialect) == [0], text
    assert matches([f], "ftp.entry.size > 5000", dialect) == []


def test_open_and_crc_acks(dialect: Dialect) -> None:
    opened = ftp_frame(dialect, op(ACK, struct.pack("<I", 17220), req=OPEN_RO, session=3))
    assert get(opened, "ftp.file_size") == 17220
    # 17220 is 44 43 00 00: a v2 sender trims the two zeros
    assert item(opened, dialect, "ftp.file_size").label == "File size: 17220 bytes [partly trimmed: zero-filled]"
    crc = ftp_frame(dialect, op(ACK, struct.pack("<I", 0xDEADBEEF), req=CRC32))
    assert get(crc, "ftp.crc32") == 0xDEADBEEF and item(crc, dialect, "ftp.crc32").label == "CRC-32: 0xdeadbeef"


def test_filters_by_name(dialect: Dialect) -> None:
    frames = [
        ftp_frame(dialect, op(OPEN_RO, b"@PARAM/param.pck")),
        ftp_frame(dialect, op(ACK, struct.pack("<I", 100), req=OPEN_RO)),
        ftp_frame(dialect, op(BURST, size=80)),
        ftp_frame(dialect, op(ACK, b"x" * 80, req=BURST)),
        ftp_frame(dialect, op(NAK, b"\x06", req=BURST, offset=160)),
        ftp_frame(dialect, op(WRITE, b"hello", offset=0)),
    ]
    assert matches(frames, "ftp.opcode == OpenFileRO", dialect) == [0]
    assert matches(frames, "ftp.opcode == 4", dialect) == [0]
    assert matches(frames, 'ftp.path contains "param.pck"', dialect) == [0]
    assert matches(frames, "ftp.error == EOF", dialect) == [4]
    assert matches(frames, "ftp.error == EndOfFile", dialect) == [4]  # pymavlink's and ArduPilot's name
    assert matches(frames, "ftp.req_opcode == BurstReadFile", dialect) == [3, 4]
    assert matches(frames, "ftp.opcode in {ACK NAK}", dialect) == [1, 3, 4]
    assert matches(frames, "ftp.opcode == Nack", dialect) == [4]
    assert matches(frames, 'ftp.data contains "hello"', dialect) == [5]
    assert matches(frames, "ftp.file_size == 100", dialect) == [1]
    assert matches(frames, "ftp.opcode != OpenFileRO", dialect) == [1, 2, 3, 4, 5]
    assert matches(frames, "ftp.malformed", dialect) == []
    with pytest.raises(FilterError, match='did you mean "OpenFileRO"'):
        compile_filter("ftp.opcode == OpenFileR0", dialect)
    with pytest.raises(FilterError, match="is not a number nor a name of ftp.error values"):
        compile_filter("ftp.error == Bogus", dialect)


@pytest.mark.parametrize("payload, problem", [
    (op(ACK, b"x" * 239, req=READ, size=250), "size 250 exceeds the 239 data bytes"),
    (op(OPEN_RO, b""), "OpenFileRO without a path (size 0)"),
    (op(NAK, b"", req=READ), "NAK without an error code (size 0)"),
    (op(NAK, b"\x02", req=READ), "FailErrno without an errno (size 1)"),
    (op(RENAME, b"/only/one"), "Rename without a second path"),
    (op(OPEN_RO, b"caf\xc3\x28.txt"), "path is not UTF-8"),
    (op(ACK, b"Fname.txt\t12", req=LIST), "has no NUL"),
    (op(ACK, b"Fname.txt\0", req=LIST), "without a size"),
    (op(ACK, b"Xwhat\0", req=LIST), "unknown type 0x58"),
    (op(ACK, b"\x01\x02", req=OPEN_RO), "OpenFileRO ACK with size 2"),
])
def test_malformed(dialect: Dialect, payload: bytes, problem: str) -> None:
    f = ftp_frame(dialect, payload)
    marker = item(f, dialect, "ftp.malformed")
    assert marker.generated and problem in marker.label and marker.label.startswith("[Malformed: ")
    assert problem in str(get(f, "ftp.malformed"))
    assert "[malformed]" in item(f, dialect, "FILE_TRANSFER_PROTOCOL.payload").label
    assert matches([f], "ftp.malformed", dialect) == [0]


def test_path_without_nul_fills_the_data(dialect: Dialect) -> None:
    path = b"p" * 239
    f = ftp_frame(dialect, op(OPEN_RO, path))
    assert get(f, "ftp.path") == "p" * 239 and wire(f, item(f, dialect, "ftp.path")) == path


def test_trimmed_payload_is_zero_filled(dialect: Dialect) -> None:
    """pymavlink trims a v2 payload's trailing zeros: the fields beyond are zero, and marked so."""
    f = ftp_frame(dialect, op(2, seq=5))  # ResetSessions: the header ends in zeros
    assert f.length < 3 + 12
    offset = item(f, dialect, "ftp.offset")
    assert offset.length == 0 and offset.label == "Offset: 0 [trimmed: zero-filled]"
    assert get(f, "ftp.offset") == 0 and get(f, "ftp.opcode") == 2


def test_other_frames_have_no_ftp_fields(dialect: Dialect) -> None:
    from tests.fields.support import frame_of
    from tests.support import pmav

    hb = frame_of(pmav.heartbeat(pmav.mav2()), dialect)
    assert all(get(hb, s) is MISSING for s in ("ftp.seq", "ftp.opcode", "ftp.data", "ftp.malformed"))
    assert not [it for it in flatten(frame_items(hb, dialect)) if it.name.startswith("ftp.")]


def test_registry_knows_the_names(dialect: Dialect) -> None:
    reg = FieldRegistry(dialect)
    names = set(reg.all_names())
    for name in ("ftp.seq", "ftp.session", "ftp.opcode", "ftp.size", "ftp.req_opcode", "ftp.burst_complete",
                 "ftp.offset", "ftp.data", "ftp.path", "ftp.error", "ftp.entry.name", "ftp.malformed"):
        assert name in names and reg.lookup(name) is field(name)
    assert field("ftp.opcode").position(ftp_frame(dialect, op(OPEN_RO, b"/x"))) == (16, 1)
    # every container item in a tree is a registered field
    f = ftp_frame(dialect, op(ACK, b"Fa\t1\0Db\0", req=LIST))
    payload = item(f, dialect, "FILE_TRANSFER_PROTOCOL.payload")
    assert all(reg.lookup(it.name) is not None for it in flatten(payload.children))


def test_json_export_unchanged(tmp_path, cli: Cli, dialect: Dialect) -> None:  # type: ignore[no-untyped-def]
    """Container fields are for the tree, filters and hex: JSON keeps the payload under "fields"."""
    from tests.fields.support import mav

    m = mav()
    msg = FTP_OP(1, 0, OPEN_RO, 4, 0, 0, 0, bytearray(b"/abc")).pack()
    data = m.file_transfer_protocol_encode(0, 1, 1, list(bytes(msg).ljust(251, b"\0"))).pack(m)
    path = tmp_path / "ftp.raw"
    path.write_bytes(data)
    [obj] = cli.jsonl(path)
    assert obj["fields"]["payload"][:16] == list(bytes(msg))
    assert "ftp" not in json.dumps(obj)
