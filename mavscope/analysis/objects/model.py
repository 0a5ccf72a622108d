"""What the object reconstruction reports, and the state of a transfer while it runs.

`ObjectRecord` is the public, frozen record of one object moved over the link (a file read or written
over MAVLink FTP, a directory listing, a log downloaded with LOG_REQUEST_DATA, an image sent as
ENCAPSULATED_DATA): who sent it to whom, when, in which frames, how much of it the capture holds, and
its bytes. `FtpOperation` is an FTP request that moved no object (a refused open, a removal, a rename, a
CRC). `Transfer` is the mutable state the trackers fill; `Transfer.record()` freezes it.
"""

from __future__ import annotations

import hashlib
import zlib
from collections import Counter
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from mavscope.analysis.objects.content import Budget, Content, Ranges
from mavscope.mavlink.frame import Addr, Frame

# Object kinds
FTP_READ, FTP_WRITE, FTP_LIST, LOG, IMAGE = "ftp-read", "ftp-write", "ftp-list", "log", "image"
KINDS = (FTP_READ, FTP_WRITE, FTP_LIST, LOG, IMAGE)
DOWNLOAD, UPLOAD = "download", "upload"


@dataclass(frozen=True, slots=True)
class Limits:
    """How much one capture may make the reconstruction hold (an attacker may have made the capture)."""

    max_object: int = 64 * 1024 * 1024  # bytes from the start of one object
    max_total: int = 256 * 1024 * 1024  # bytes held by all objects not yet handed over
    max_holes: int = 256 * 1024 * 1024  # bytes never received that objects hold as zeros, all objects together
    max_open: int = 256  # transfers in progress at once; the least recently active one is closed early
    max_objects: int = 50_000  # objects reported; later ones are counted, not kept
    max_ranges: int = 65_536  # separate pieces of one object
    max_frames: int = 4096  # frame numbers listed per object (all are counted)
    max_entries: int = 65_536  # entries of one directory listing
    max_operations: int = 10_000  # FTP operations listed


def int_field(fields: dict[str, object], name: str) -> int:
    """An integer field of a decoded payload (0 where it is missing or not an integer: another dialect)."""
    v = fields.get(name, 0)
    return v if isinstance(v, int) else 0


def party(addr: Addr | None) -> str:
    return "-" if addr is None else f"{addr[0]}/{addr[1]}"


def verdict(f: Frame) -> str:
    """A frame's signature verdict as the JSON names it ("unsigned" for a frame without a signature)."""
    status = f.signature_status
    return "unsigned" if status is None else status.value


@dataclass(frozen=True, slots=True)
class ObjectRecord:
    """One object moved over the link, as the capture holds it."""

    number: int  # 1-based, in the order the transfers started
    kind: str  # ftp-read, ftp-write, ftp-list, log, image
    path: str | None  # the path on the vehicle (FTP); None for logs, images and FTP data without its open
    name: str  # a label: the path, "log 3", "image 12"
    file: str  # the object's file name in an output directory (a single safe path component)
    direction: str  # "download" (vehicle to GCS) or "upload" (GCS to vehicle)
    sender: Addr | None  # who sent the bytes
    receiver: Addr | None  # who they went to (None: not named by any frame)
    start: float | None  # capture time of the transfer's first frame
    end: float | None  # ... and of its last one
    first_frame: int
    last_frame: int
    frames: tuple[int, ...]  # frame numbers of the transfer (requests and replies), at most Limits.max_frames
    frame_count: int
    size: int  # bytes of the object as written (gaps zero-filled)
    announced_size: int | None  # what the protocol announced (FTP open ACK, LOG_ENTRY, image handshake)
    received: int  # distinct bytes (listings: entries) the capture holds
    gaps: tuple[tuple[int, int], ...]  # [start, end) never received, in `gap_unit`
    gap_unit: str  # "bytes", or "entries" for a listing
    complete: bool  # every byte (entry) of it is in the capture and its end is known
    end_known: bool  # the end came from the protocol (EOF, announced size, handshake), not the last byte seen
    sha256: str
    crc32: int
    duplicate_bytes: int
    conflict_bytes: int  # bytes received again with another value (the first copy is kept)
    dropped_bytes: int  # bytes a limit kept out
    signatures: MappingProxyType[str, MappingProxyType[str, int]]  # party -> signature verdict -> frames
    problems: tuple[str, ...]
    details: MappingProxyType[str, Any]  # per kind: session, log id, image geometry, listing entries...
    data: bytes = field(repr=False, compare=False)

    @property
    def signed_frames(self) -> int:
        return sum(n for v in self.signatures.values() for k, n in v.items() if k != "unsigned")


@dataclass(frozen=True, slots=True)
class FtpOperation:
    """An FTP request that moved no object: what was asked, and the server's answer."""

    time: float | None
    frame: int
    client: Addr
    server: Addr | None
    opcode: str  # OpenFileRO, CreateFile, RemoveFile, Rename, CalcFileCRC32...
    path: str | None
    new_path: str | None
    result: str | None  # "ACK", "NAK <error>", None (no answer in the capture)
    reply_frame: int | None
    detail: str = ""  # a CRC-32, an errno


class FrameList:
    """The frame numbers of a transfer: the first `limit` kept, all counted."""

    __slots__ = ("nums", "count", "limit", "first", "last", "start", "end")

    def __init__(self, limit: int) -> None:
        self.nums: list[int] = []
        self.count = 0
        self.limit = limit
        self.first = 0
        self.last = 0
        self.start: float | None = None
        self.end: float | None = None

    def add(self, f: Frame) -> None:
        if not self.count:
            self.first = f.record
            self.start = f.time
        self.count += 1
        self.last = f.record
        if f.time is not None:
            self.end = f.time
            if self.start is None:
                self.start = f.time
        if len(self.nums) < self.limit and (not self.nums or self.nums[-1] != f.record):
            self.nums.append(f.record)


@dataclass
class Transfer:
    """A transfer in progress."""

    kind: str
    direction: str
    sender: Addr | None
    receiver: Addr | None
    content: Content
    frames: FrameList
    path: str | None = None
    name: str = ""
    announced: int | None = None  # size the protocol announced
    end_at: int | None = None  # where the protocol said the object ends (EOF NAK, short LOG_DATA)
    closed: bool = False  # the session ended (TerminateSession, LOG_REQUEST_END, a new handshake)
    order: int = 0  # the sequence number the reconstruction gave it when it started
    acked: Ranges | None = None  # uploads: the bytes the server acknowledged
    signatures: dict[str, Counter[str]] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
    last_seen: int = 0  # activity counter (for closing the least recently active transfer early)

    def see(self, f: Frame, tick: int) -> None:
        self.frames.add(f)
        who = f"{f.sysid}/{f.compid}"
        counts = self.signatures.get(who)
        if counts is None:
            counts = self.signatures[who] = Counter()
        counts[verdict(f)] += 1
        self.last_seen = tick

    def problem(self, text: str) -> None:
        if text not in self.problems and len(self.problems) < 32:
            self.problems.append(text)


def record_of(t: Transfer, number: int, file: str, size: int, gaps: list[tuple[int, int]], end_known: bool,
              complete: bool, data: bytes, received: int, gap_unit: str = "bytes") -> ObjectRecord:
    """Freeze a finished transfer (the caller decided its size, gaps and bytes)."""
    c = t.content
    problems = list(t.problems) + sorted(c.problems)
    return ObjectRecord(
        number=number, kind=t.kind, path=t.path, name=t.name or (t.path or t.kind), file=file,
        direction=t.direction, sender=t.sender, receiver=t.receiver, start=t.frames.start, end=t.frames.end,
        first_frame=t.frames.first, last_frame=t.frames.last, frames=tuple(t.frames.nums),
        frame_count=t.frames.count, size=size, announced_size=t.announced, received=received,
        gaps=tuple(gaps), gap_unit=gap_unit, complete=complete, end_known=end_known,
        sha256=hashlib.sha256(data).hexdigest(), crc32=zlib.crc32(data), duplicate_bytes=c.duplicates,
        conflict_bytes=c.conflicts, dropped_bytes=c.dropped,
        signatures=MappingProxyType({k: MappingProxyType(dict(sorted(v.items())))
                                     for k, v in sorted(t.signatures.items())}),
        problems=tuple(problems), details=MappingProxyType(dict(t.details)), data=data)


def new_transfer(kind: str, direction: str, sender: Addr | None, receiver: Addr | None, budget: Budget,
                 limits: Limits) -> Transfer:
    return Transfer(kind, direction, sender, receiver, Content(budget, limits.max_object, limits.max_ranges),
                    FrameList(limits.max_frames))
