"""Telemetry-log entries that hold no MAVLink at all, joined into one problem per run.

MAVProxy writes what it could not parse into the tlog as entries of their own: a SITL's console text
arrives one byte an entry ("I", "n", "i", "t", ...), pymavlink's BAD_DATA as a chunk. Reported one entry
at a time that is a line per byte on stderr; joined, it reads as what it was (`tlog entries 1-15: 15 bytes
that are not MAVLink: 'Init ArduRover\\n'`). A run ends at the next entry that may hold a frame, at the end
of the capture, or after MAX_BYTES (so its memory is bounded).
"""

from __future__ import annotations

from mavscope.capture.base import LINKTYPE_MAVLINK_TLOG, Record
from mavscope.notes import Note, note
from mavscope.visible import quoted

MAX_BYTES = 4096  # bytes a run keeps before it is reported and a new one starts
PREVIEW = 160  # characters of the text shown


def is_text_entry(rec: Record) -> bool:
    """Whether `rec` is a tlog entry whose bytes cannot hold a MAVLink frame (no STX byte at all)."""
    data = rec.data
    return (rec.linktype == LINKTYPE_MAVLINK_TLOG and bool(data) and not rec.notes
            and b"\xfd" not in data and b"\xfe" not in data)


class TextRun:
    """Consecutive non-MAVLink tlog entries, kept until `take()`."""

    __slots__ = ("first", "last", "entries", "offset", "data")

    def __init__(self) -> None:
        self.first = self.last = self.entries = 0
        self.offset = 0
        self.data = bytearray()

    def __bool__(self) -> bool:
        return self.entries > 0

    def add(self, rec: Record) -> bool:
        """Add an entry; True when the run is full and should be taken now."""
        if not self.entries:
            self.first, self.offset = rec.number, rec.offset
        self.last = rec.number
        self.entries += 1
        self.data += rec.data
        return len(self.data) >= MAX_BYTES

    def take(self) -> tuple[int, Note]:
        """(first record, the note) of the run so far; the run starts over."""
        text = self.data.decode("utf-8", "backslashreplace")
        shown = quoted(text[:PREVIEW]) + ("..." if len(text) > PREVIEW else "")  # (escaped once where shown)
        which = f"tlog entry {self.first}" if self.entries == 1 else f"tlog entries {self.first}-{self.last}"
        size = len(self.data)
        result = (self.first, note("tlog-text", f"{which}: {size} {'byte that is' if size == 1 else 'bytes that are'} "
                                   f"not MAVLink (text a logger wrote, or data it could not parse): {shown}",
                                   self.offset))
        self.first = self.last = self.entries = 0
        self.data = bytearray()
        return result
