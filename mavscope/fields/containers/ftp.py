"""MAVLink FTP inside FILE_TRANSFER_PROTOCOL.payload (https://mavlink.io/en/services/ftp.html).

The payload is a 12-byte header and up to 239 bytes of data:

    seq_number uint16, session uint8, opcode uint8, size uint8, req_opcode uint8, burst_complete uint8,
    padding uint8, offset uint32, data[239]                                           (little-endian)

as pymavlink's `mavftp_op.FTP_OP.pack`, ArduPilot's `GCS_FTP` and PX4's `MavlinkFTP` lay it out. `size`
says how many data bytes count. What the data holds depends on the opcode: a path for the requests
that name a file or directory (Rename: two paths separated by a NUL), file bytes in ReadFile and
BurstReadFile ACKs and WriteFile requests, the error code (and for FailErrno the errno) in a NAK, the
file size in the ACK of an open (PX4 for OpenFileRO, OpenFileWO and CreateFile, ArduPilot for
OpenFileRO), the CRC-32 in a CalcFileCRC32 ACK, and directory entries ("F<name>\\t<size>\\0",
"D<name>\\0", "S<name>\\0") in a ListDirectory ACK.

Per frame and stateless: a response says which request it answers (`req_opcode`), so nothing here
needs the frames before it.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

from mavscope.fields.containers.base import (
    BYTES,
    INT,
    NONE,
    STR,
    Get,
    Node,
    Region,
    Spec,
    Where,
    byte_field,
    hex_text,
    memo,
    message,
    plural,
    text,
    trimmed,
)
from mavscope.mavlink.frame import Frame

MESSAGE = "FILE_TRANSFER_PROTOCOL"
HEADER = struct.Struct("<HBBBBBBI")  # seq_number, session, opcode, size, req_opcode, burst_complete, padding, offset

# Opcodes and NAK errors with the spec's names; then the names pymavlink and ArduPilot use, which a
# filter accepts as well (the first name of a value is the one shown).
OPCODES: tuple[tuple[int, str], ...] = (
    (0, "None"), (1, "TerminateSession"), (2, "ResetSessions"), (3, "ListDirectory"), (4, "OpenFileRO"),
    (5, "ReadFile"), (6, "CreateFile"), (7, "WriteFile"), (8, "RemoveFile"), (9, "CreateDirectory"),
    (10, "RemoveDirectory"), (11, "OpenFileWO"), (12, "TruncateFile"), (13, "Rename"), (14, "CalcFileCRC32"),
    (15, "BurstReadFile"), (128, "ACK"), (129, "NAK"),
    (128, "Ack"), (129, "Nack"), (129, "NACK"),
)
ERRORS: tuple[tuple[int, str], ...] = (
    (0, "None"), (1, "Fail"), (2, "FailErrno"), (3, "InvalidDataSize"), (4, "InvalidSession"),
    (5, "NoSessionsAvailable"), (6, "EOF"), (7, "UnknownCommand"), (8, "FileExists"), (9, "FileProtected"),
    (10, "FileNotFound"),
    (6, "EndOfFile"),
)
_OPCODE = {v: n for v, n in reversed(OPCODES)}
_ERROR = {v: n for v, n in reversed(ERRORS)}

TERMINATE, RESET, LIST, OPEN_RO, READ, CREATE, WRITE = 1, 2, 3, 4, 5, 6, 7
OPEN_WO, RENAME, CRC32, BURST, ACK, NAK = 11, 13, 14, 15, 128, 129
FAIL_ERRNO = 2
# Requests whose data is a path (Rename: two).
PATH_OPCODES = frozenset({3, 4, 6, 8, 9, 10, 11, 12, 13, 14})
# ACKs whose data is file bytes.
DATA_ACKS = frozenset({READ, BURST})
ENTRY_KINDS = {"F": "file", "D": "directory", "S": "skip"}


def value_text(names: dict[int, str], value: int) -> str:
    name = names.get(value)
    return f"{name} ({value})" if name is not None else f"unknown ({value})"


def opcode_name(value: int) -> str:
    return _OPCODE.get(value, f"opcode {value}")


class Entry(NamedTuple):
    """One ListDirectory entry: positions are within the data field."""

    start: int
    length: int  # without its NUL
    kind: str  # file, directory, skip, unknown
    name: str
    name_length: int  # bytes of the name on the wire
    size: int | None  # files only
    size_start: int  # where the size digits begin (files)
    size_length: int


class Ftp(NamedTuple):
    """One FTP packet and what its data means."""

    region: Region  # FILE_TRANSFER_PROTOCOL.payload
    seq: int
    session: int
    opcode: int
    size: int
    req_opcode: int
    burst_complete: int
    padding: int
    offset: int
    data: bytes  # the `size` valid data bytes (at most 239)
    path: str | None  # a path request's path (Rename: the old one)
    new_path: str | None  # Rename: the new path
    error: int | None  # NAK: data[0]
    errno: int | None  # NAK FailErrno: data[1]
    file_size: int | None  # ACK of an open: the file's size
    crc32: int | None  # ACK of CalcFileCRC32
    entries: tuple[Entry, ...]  # ACK of ListDirectory
    problems: tuple[str, ...]  # why the packet is malformed (empty: it is not)

    def span(self, start: int, size: int) -> tuple[int, int]:
        """Offset in the frame and bytes on the wire of `size` bytes at `start` in the FTP payload."""
        return self.region.span(start, size)


def _entries(data: bytes, problems: list[str]) -> tuple[Entry, ...]:
    out: list[Entry] = []
    pos = 0
    while pos < len(data):
        end = data.find(b"\0", pos)
        if end < 0:
            end = len(data)
            problems.append(f"directory entry at data byte {pos} has no NUL")
        raw = data[pos:end]
        if raw:  # an empty entry (a stray NUL) is no entry
            kind = ENTRY_KINDS.get(chr(raw[0]), "unknown")
            name_raw, tab, rest = raw[1:].partition(b"\t")
            name, ok = text(name_raw)
            if not ok:
                problems.append(f"directory entry name {name!r} is not UTF-8")
            if kind == "unknown":
                problems.append(f"directory entry of unknown type 0x{raw[0]:02x}")
            size = None
            size_raw = rest.partition(b"\t")[0]  # (a server may add a tab and more: only the size counts)
            size_start = pos + 1 + len(name_raw) + len(tab)
            if kind == "file":
                if size_raw.isdigit():  # bytes: ASCII digits only
                    size = int(size_raw)
                else:
                    problems.append(f"file entry {name!r} without a size")
            out.append(Entry(pos, len(raw), kind, name, len(name_raw), size, size_start,
                             len(size_raw) if size is not None else 0))
        pos = end + 1
    return tuple(out)


def _uint32(data: bytes) -> int:
    return int.from_bytes(data[:4], "little")


@memo
def ftp(frame: Frame) -> Ftp | None:
    """The FTP packet in `frame`, None if it is no (decodable) FILE_TRANSFER_PROTOCOL."""
    msg = message(frame, MESSAGE)
    if msg is None:
        return None
    fd = byte_field(msg.md, "payload")
    if fd is None or fd.size < HEADER.size:
        return None
    region = msg.region(frame, fd)
    seq, session, opcode, size, req, burst, padding, offset = HEADER.unpack_from(region.data)
    room = fd.size - HEADER.size
    problems: list[str] = []
    if size > room:
        problems.append(f"size {size} exceeds the {room} data bytes")
    # in a ReadFile or BurstReadFile request, size is how much to read: the data field carries nothing
    data = b"" if opcode in (READ, BURST) else region.data[HEADER.size : HEADER.size + min(size, room)]
    path = new_path = None
    error = errno = file_size = crc = None
    entries: tuple[Entry, ...] = ()
    if opcode in PATH_OPCODES:
        if not data:
            problems.append(f"{opcode_name(opcode)} without a path (size 0)")
        else:
            parts = data.split(b"\0")
            path, ok = text(parts[0])
            if not path:
                problems.append("empty path")
            if opcode == RENAME:
                if len(parts) > 1 and parts[1]:
                    new_path, ok2 = text(parts[1])
                    ok = ok and ok2
                else:
                    problems.append("Rename without a second path")
            if not ok:
                problems.append("path is not UTF-8 (undecodable bytes shown escaped)")
    elif opcode == NAK:
        if not data:
            problems.append("NAK without an error code (size 0)")
        else:
            error = data[0]
            if error == FAIL_ERRNO:
                if len(data) >= 2:
                    errno = data[1]
                else:
                    problems.append("FailErrno without an errno (size 1)")
    elif opcode == ACK:
        if req in (OPEN_RO, OPEN_WO, CREATE) and size == 4:
            file_size = _uint32(data)
        elif req == OPEN_RO:
            problems.append(f"OpenFileRO ACK with size {size}, not 4 (the file size)")
        elif req == CRC32:
            if size == 4:
                crc = _uint32(data)
            else:
                problems.append(f"CalcFileCRC32 ACK with size {size}, not 4 (the CRC-32)")
        elif req == LIST:
            entries = _entries(data, problems)
    return Ftp(region, seq, session, opcode, size, req, burst, padding, offset, data, path, new_path, error,
               errno, file_size, crc, entries, tuple(problems))


# --- registered fields -------------------------------------------------------------------------------

def _get(attr: str, *, empty: object = None) -> Get:
    def get(frame: Frame) -> object:
        p = ftp(frame)
        if p is None:
            return None
        value = getattr(p, attr)
        return None if value == empty else value
    return get


def _header_span(start: int, size: int) -> Where:
    def span(frame: Frame) -> tuple[int, int] | None:
        p = ftp(frame)
        return None if p is None else p.span(start, size)
    return span


def _data_span(frame: Frame) -> tuple[int, int] | None:
    p = ftp(frame)
    return None if p is None or not p.data else p.span(HEADER.size, len(p.data))


def _entry_values(attr: str) -> Get:
    def get(frame: Frame) -> object:
        p = ftp(frame)
        if p is None or not p.entries:
            return None
        values = tuple(v for v in (getattr(e, attr) for e in p.entries) if v is not None and v != "")
        return values or None
    return get


def _has_entries(frame: Frame) -> object:
    p = ftp(frame)
    return True if p is not None and p.entries else None


def _problems(frame: Frame) -> object:
    p = ftp(frame)
    return "; ".join(p.problems) if p is not None and p.problems else None


# (name, label, byte offset in the FTP payload, bytes, description) of the header, in wire order
_HEADER_FIELDS = (
    ("ftp.seq", "Sequence number", 0, 2, "seq_number: FTP sequence number (a response carries the request's + 1)"),
    ("ftp.session", "Session", 2, 1, "session id"),
    ("ftp.opcode", "Opcode", 3, 1, "opcode, by number or name: OpenFileRO, BurstReadFile, ACK, NAK..."),
    ("ftp.size", "Size", 4, 1, "number of valid data bytes"),
    ("ftp.req_opcode", "Request opcode", 5, 1, "in an ACK or NAK: the opcode of the request it answers"),
    ("ftp.burst_complete", "Burst complete", 6, 1, "1 on the last packet of a burst"),
    ("ftp.padding", "Padding", 7, 1, "alignment byte"),
    ("ftp.offset", "Offset", 8, 4, "file offset (ListDirectory: first entry index; TruncateFile: length)"),
)
_VALUES = {"ftp.opcode": OPCODES, "ftp.req_opcode": OPCODES}

SPECS: tuple[Spec, ...] = (
    *(Spec(name, label, INT, _get(name[4:]), _header_span(start, size),
           values=_VALUES.get(name, ()), description=desc)
      for name, label, start, size, desc in _HEADER_FIELDS),
    Spec("ftp.data", "Data", BYTES, _get("data", empty=b""), _data_span,
         description="the `size` valid data bytes (absent when size is 0, and in a ReadFile or BurstReadFile "
                     "request, whose size is the length to read)"),
    Spec("ftp.path", "Path", STR, _get("path"),
         description="the path of ListDirectory, OpenFileRO/WO, CreateFile, RemoveFile, CreateDirectory, "
                     "RemoveDirectory, TruncateFile, Rename (old), CalcFileCRC32"),
    Spec("ftp.new_path", "New path", STR, _get("new_path"), description="Rename: the new path"),
    Spec("ftp.error", "Error", INT, _get("error"), values=ERRORS,
         description="NAK error code (data[0]), by number or name: EOF, FileNotFound, InvalidSession..."),
    Spec("ftp.errno", "Errno", INT, _get("errno"), description="NAK FailErrno: the server's errno (data[1])"),
    Spec("ftp.file_size", "File size", INT, _get("file_size"),
         description="ACK of OpenFileRO (PX4: also OpenFileWO, CreateFile): the file's size"),
    Spec("ftp.crc32", "CRC-32", INT, _get("crc32"), description="ACK of CalcFileCRC32: the file's CRC-32"),
    Spec("ftp.entry", "Entry", NONE, _has_entries, description="present on a ListDirectory ACK with entries"),
    Spec("ftp.entry.type", "Type", STR, _entry_values("kind"), choices=("file", "directory", "skip", "unknown"),
         multi=True, description="directory entry types: file (F), directory (D), skip (S)"),
    Spec("ftp.entry.name", "Name", STR, _entry_values("name"), multi=True, description="directory entry names"),
    Spec("ftp.entry.size", "Size", INT, _entry_values("size"), multi=True, description="file entry sizes"),
    Spec("ftp.malformed", "Malformed", STR, _problems,
         description="why the FTP packet is malformed (size > 239, a NAK without error, a path op without path...)"),
)
LABELS = {s.name: s.label for s in SPECS}


# --- the tree ---------------------------------------------------------------------------------------------

def _node(p: Ftp, name: str, start: int, size: int, value: object, shown: str) -> Node:
    off, length = p.span(start, size)
    return Node(f"{LABELS[name]}: {shown}{trimmed(length, size)}", name, off, length, value)


def _entry_node(p: Ftp, e: Entry, number: int) -> Node:
    base = HEADER.size + e.start
    desc = {"file": f"file {e.name!r}" + (f", {e.size} bytes" if e.size is not None else ""),
            "directory": f"directory {e.name!r}", "skip": "skipped" + (f" {e.name!r}" if e.name else "")}
    children = [_node(p, "ftp.entry.type", base, 1, e.kind, f"{e.kind} ({chr(p.data[e.start])})")]
    if e.name_length:
        children.append(_node(p, "ftp.entry.name", base + 1, e.name_length, e.name, repr(e.name)))
    if e.size is not None:
        children.append(_node(p, "ftp.entry.size", HEADER.size + e.size_start, e.size_length, e.size, str(e.size)))
    off, length = p.span(base, e.length + 1)
    text_ = desc.get(e.kind, f"unknown type 0x{p.data[e.start]:02x}")
    return Node(f"{LABELS['ftp.entry']} {number}: {text_}", "ftp.entry", off, length, None, tuple(children))


def _data_node(p: Ftp) -> Node | None:
    if not p.data:
        return None
    size = len(p.data)
    children: list[Node] = []
    start = HEADER.size
    if p.path is not None:
        raw_len = p.data.find(b"\0")
        first = size if raw_len < 0 else raw_len
        children.append(_node(p, "ftp.path", start, first, p.path, repr(p.path)))
        if p.new_path is not None:
            second = p.data.find(b"\0", first + 1)
            end = size if second < 0 else second
            children.append(_node(p, "ftp.new_path", start + first + 1, end - first - 1, p.new_path, repr(p.new_path)))
    if p.error is not None:
        children.append(_node(p, "ftp.error", start, 1, p.error, value_text(_ERROR, p.error)))
        if p.errno is not None:
            children.append(_node(p, "ftp.errno", start + 1, 1, p.errno, str(p.errno)))
    if p.file_size is not None:
        children.append(_node(p, "ftp.file_size", start, 4, p.file_size, f"{p.file_size} bytes"))
    if p.crc32 is not None:
        children.append(_node(p, "ftp.crc32", start, 4, p.crc32, f"0x{p.crc32:08x}"))
    children.extend(_entry_node(p, e, i) for i, e in enumerate(p.entries, 1))
    off, length = p.span(start, size)
    label = f"{LABELS['ftp.data']} ({plural(size)})"
    if not children:
        label += f": {hex_text(p.data)}"
    return Node(label + trimmed(length, size), "ftp.data", off, length, p.data, tuple(children))


def summary(p: Ftp) -> str:
    """The FILE_TRANSFER_PROTOCOL.payload line: what the packet is."""
    op = opcode_name(p.opcode)
    if p.opcode == ACK:
        what = f"ACK ({opcode_name(p.req_opcode)})"
        if p.req_opcode in DATA_ACKS:
            what += f", {plural(len(p.data))} at offset {p.offset}"
            if p.req_opcode == BURST and p.burst_complete:
                what += ", burst complete"
        elif p.file_size is not None:
            what += f", file size {p.file_size}"
        elif p.crc32 is not None:
            what += f", CRC-32 0x{p.crc32:08x}"
        elif p.req_opcode == LIST:
            what += f", {len(p.entries)} entries"
    elif p.opcode == NAK:
        what = f"NAK ({opcode_name(p.req_opcode)})"
        if p.error is not None:
            what += f": {_ERROR.get(p.error, f'error {p.error}')}"
            if p.errno is not None:
                what += f" (errno {p.errno})"
    else:
        what = op
        if p.path is not None:
            what += f" {p.path!r}"
            if p.new_path is not None:
                what += f" -> {p.new_path!r}"
        if p.opcode in (READ, BURST):
            what += f", offset {p.offset}, size {p.size}"
        elif p.opcode == WRITE:
            what += f", {plural(len(p.data))} at offset {p.offset}"
        elif p.opcode == LIST:
            what += f", from entry {p.offset}"
    text_ = f"MAVLink FTP {what}, seq {p.seq}, session {p.session}"
    return text_ + (" [malformed]" if p.problems else "")


def subtree(frame: Frame) -> tuple[str, tuple[Node, ...]] | None:
    """The summary of FILE_TRANSFER_PROTOCOL.payload and the FTP fields under it."""
    p = ftp(frame)
    if p is None:
        return None
    shown = {"ftp.opcode": value_text(_OPCODE, p.opcode), "ftp.req_opcode": value_text(_OPCODE, p.req_opcode)}
    nodes = [_node(p, name, start, size, getattr(p, name[4:]), shown.get(name, str(getattr(p, name[4:]))))
             for name, _label, start, size, _desc in _HEADER_FIELDS]
    data = _data_node(p)
    if data is not None:
        nodes.append(data)
    if p.problems:
        problem = "; ".join(p.problems)
        nodes.append(Node(f"[Malformed: {problem}]", "ftp.malformed", p.region.base, 0, problem, (), True))
    return summary(p), tuple(nodes)
