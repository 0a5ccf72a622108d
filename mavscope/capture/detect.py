"""Open a capture file whatever its format, recognised by its content (never by its name)."""

from __future__ import annotations

import os

from mavscope.capture.pcap import PcapReader, sniff_pcap
from mavscope.capture.pcapng import PcapngReader, sniff_pcapng
from mavscope.capture.raw import RawReader
from mavscope.capture.reader import CaptureReader, open_mapped
from mavscope.capture.tlog import TlogReader, sniff_tlog

__all__ = ["CaptureReader", "detect_kind", "open_capture"]


def detect_kind(path: str | os.PathLike[str]) -> str:
    """The format of a capture file: "pcap", "pcapng", "tlog" or "raw" (CaptureError if unreadable)."""
    _, f, buf, size = open_mapped(path)
    try:
        head = bytes(buf[:16])
        if sniff_pcapng(head):
            return "pcapng"
        if sniff_pcap(head):
            return "pcap"
        if sniff_tlog(buf, size):
            return "tlog"
        return "raw"
    finally:
        if not isinstance(buf, bytes):
            buf.close()
        f.close()  # type: ignore[attr-defined]


_READERS: dict[str, type[CaptureReader]] = {
    "pcap": PcapReader,
    "pcapng": PcapngReader,
    "tlog": TlogReader,
    "raw": RawReader,
}


def open_capture(path: str | os.PathLike[str]) -> CaptureReader:
    """Open a capture for reading, choosing the reader by the file's content.

    Raises CaptureError when the file is missing, unreadable or not a regular file.
    An empty file is a valid capture with no records.
    """
    return _READERS[detect_kind(path)](path)
