"""Open a capture file whatever its format, recognised by its content (never by its name)."""

from __future__ import annotations

import os
import sys
from typing import BinaryIO, cast

from mavscope.capture.pcap import PcapReader, sniff_pcap
from mavscope.capture.pcapng import PcapngReader, sniff_pcapng
from mavscope.capture.raw import RawReader
from mavscope.capture.reader import CaptureReader, open_file, pread
from mavscope.capture.stream import STDIN, UNKNOWN_SIZE, StreamBytes
from mavscope.capture.tlog import TlogReader, sniff_tlog
from mavscope.errors import CaptureError

__all__ = ["CaptureReader", "detect_kind", "open_capture"]

# Bytes read to recognise a format: sniff_tlog looks at two entries and at most 4 KiB beyond the first.
SNIFF = 65536


def detect_kind(path: str | os.PathLike[str]) -> str:
    """The format of a capture file: "pcap", "pcapng", "tlog" or "raw" (CaptureError if unreadable)."""
    spath, f, size = open_file(path)
    try:
        try:
            head = pread(f, min(size, SNIFF), 0)
        except OSError as e:
            raise CaptureError(f"cannot read: {e.strerror or e}", path=spath) from None
        return kind_of(head, size)
    finally:
        f.close()


def kind_of(head: bytes, size: int) -> str:
    """The format whose first bytes are `head` (at most SNIFF of them) in a capture of `size` bytes."""
    if sniff_pcapng(head[:16]) or (size < 12 and head[:4] == b"\x0a\x0d\x0d\x0a"):
        return "pcapng"  # (a file that ends inside the section header is a pcapng cut short, not raw bytes)
    if sniff_pcap(head[:16]):
        return "pcap"
    if sniff_tlog(head, len(head)):
        return "tlog"
    return "raw"


_READERS: dict[str, type[CaptureReader]] = {
    "pcap": PcapReader,
    "pcapng": PcapngReader,
    "tlog": TlogReader,
    "raw": RawReader,
}


def open_capture(path: str | os.PathLike[str]) -> CaptureReader:
    """Open a capture for reading, choosing the reader by the file's content; `-` reads standard input
    (capture.stream: a pipe, in bounded memory).

    Raises CaptureError when the file is missing, unreadable or not a regular file.
    An empty file is a valid capture with no records.
    """
    if os.fspath(path) == STDIN:
        return open_stream(sys.stdin.buffer)
    return _READERS[detect_kind(path)](path)


def open_stream(f: BinaryIO) -> CaptureReader:
    """A capture read from the stream `f` (its format by its first bytes)."""
    source = StreamBytes(f)
    head = source.read_at(0, 16)  # a pcap or pcapng says so at once (a live pipe need not fill SNIFF first)
    if not (sniff_pcapng(head) or sniff_pcap(head)):
        head = source.read_at(0, SNIFF)
    kind = kind_of(head, len(head) if len(head) < SNIFF and source.ended else UNKNOWN_SIZE)
    return _READERS[kind](cast("str", source))  # (a reader takes a StreamBytes where it takes a path)
