"""Classic libpcap files: both byte orders, microsecond and nanosecond timestamps."""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator

from mavscope.capture.base import Record
from mavscope.capture.reader import READER_BUGS, CaptureReader, make_record
from mavscope.errors import CaptureError
from mavscope.notes import Note, note

MAGIC_US = 0xA1B2C3D4
MAGIC_NS = 0xA1B23C4D
MIN_MAX_RECORD = 262144  # a record longer than max(snaplen, this) is taken as a corrupt header
RESYNC_WINDOW = 86400  # seconds a resynchronised record may lie after the last good one (and 1/24 before)

_GLOBAL = {e: struct.Struct(e + "IHHiIII") for e in "<>"}
_RECORD = {e: struct.Struct(e + "IIII") for e in "<>"}


def sniff_pcap(head: bytes) -> str | None:
    """The byte order ("<" or ">") if `head` starts a pcap file, else None."""
    if len(head) < 4:
        return None
    for e in "<>":
        if struct.unpack_from(e + "I", head)[0] in (MAGIC_US, MAGIC_NS):
            return e
    return None


class PcapReader(CaptureReader):
    """Reads a classic pcap file record by record, a window of the file at a time.

    Record times are `sec + frac / units` as the file has them (0 .. about 2**32 + 4295 seconds: a
    fraction is not checked against its unit), never None for a complete record header.
    """

    kind = "pcap"

    def __init__(self, path: str | os.PathLike[str]) -> None:
        super().__init__(path)
        try:
            head = self.read_at(0, 40)
        except OSError as e:
            self.close()
            raise CaptureError(f"cannot read: {e.strerror or e}", path=self.path) from None
        self.endian = sniff_pcap(head[:4]) or "<"
        magic = struct.unpack_from(self.endian + "I", head)[0] if len(head) >= 4 else MAGIC_US
        self.nanosecond = magic == MAGIC_NS
        self.snaplen = 0
        self.linktype = 1
        self.version = (2, 4)
        self._header_ok = len(head) >= 24
        self._first_sec = _RECORD[self.endian].unpack_from(head, 24)[0] if len(head) >= 40 else -1
        if self._header_ok:
            _, vmaj, vmin, _, _, snaplen, network = _GLOBAL[self.endian].unpack_from(head, 0)
            self.version = (vmaj, vmin)
            self.snaplen = snaplen
            self.linktype = network & 0xFFFF  # upper bits may carry FCS information
        self._linktype = self.linktype

    def _records(self) -> Iterator[Record]:
        size = self.size
        linktype = self.linktype
        if not self._header_ok:
            self.position = size
            head: tuple[Note, ...] = ()
            if size:
                head = (note("record-truncated", f"file ends {size} bytes into the 24-byte pcap header", 0),)
            head += self.shrink_notes()
            if head:
                yield make_record(1, None, linktype, b"", 0, 0, head)
            return
        unpack = _RECORD[self.endian].unpack_from
        div = 1_000_000_000 if self.nanosecond else 1_000_000
        maxlen = max(self.snaplen, MIN_MAX_RECORD)
        tuple_new = tuple.__new__
        R = Record
        n = 0
        pos = base = 24
        buf = b""
        last_sec = self._first_sec
        pending: tuple[Note, ...] = ()
        try:
            buf = self.window_at(base)
            size = self.size
            while True:
                # the common case, kept tight: complete, unsnapped records while there is nothing to report
                if not pending:
                    blen = len(buf)
                    p = pos - base
                    last = blen - 16
                    while p <= last:
                        sec, frac, incl, orig = unpack(buf, p)
                        start = p + 16
                        end = start + incl
                        if end > blen or incl > maxlen or orig != incl:
                            break
                        n += 1
                        yield tuple_new(R, (n, sec + frac / div, linktype, buf[start:end], base + start, orig, ()))
                        p = end
                        if not n & 1023:
                            self.position = base + p
                            last_sec = sec  # resynchronisation looks for timestamps near this one
                    pos = base + p
                self.position = pos
                have = base + len(buf)  # the window holds the file's bytes up to here
                if pos + 16 > have and have < size:  # the next header crosses the window: read on from it
                    buf, base = self.window_at(pos), pos
                    size = self.size
                    continue
                if pos > size - 16:
                    end_notes = pending
                    if pos < size:
                        end_notes += (note("record-truncated",
                                           f"file ends {size - pos} bytes into a 16-byte record header at offset {pos}",
                                           pos),)
                    end_notes += self.shrink_notes()
                    self.position = size
                    if end_notes:
                        n += 1
                        yield make_record(n, None, linktype, b"", pos, 0, end_notes)
                    return
                sec, frac, incl, orig = unpack(buf, pos - base)
                if incl > maxlen:
                    found = self._resync(pos, last_sec, maxlen, div)
                    size = self.size
                    if found < 0:
                        what = f"corrupt record header at offset {pos} (length {incl}); no later record found"
                        pending += (note("capture-garbage", f"{what}, {size - pos} bytes skipped", pos),)
                        pos = size
                        continue
                    pending += (note("capture-garbage",
                                     f"corrupt record header at offset {pos}: {found - pos} bytes skipped", pos),)
                    pos = found
                    continue
                start = pos + 16
                end = start + incl
                if end > have and have < size:  # the record crosses the window: read it whole
                    buf, base = self.window_at(pos, 16 + incl), pos
                    size = self.size
                    continue
                last_sec = sec
                n += 1
                if end > size:
                    pending += (note("record-truncated",
                                     f"record at offset {pos} has {size - start} of {incl} bytes: file cut short",
                                     pos),)
                    end = size
                if orig < incl:
                    orig = incl  # lenient: some writers leave orig_len 0 or short
                elif orig > incl:
                    pending += (note("record-snapped", f"{incl} of {orig} bytes captured", start),)
                self.position = end
                yield make_record(n, sec + frac / div, linktype, buf[start - base:end - base], start, orig, pending)
                pending = ()
                pos = end
        except READER_BUGS as exc:
            yield self.failure(n + 1, pos, exc, pending)

    def _plausible(self, p: int, last_sec: int, maxlen: int, div: int) -> bool:
        """Whether a record header at `p` looks sane, its record fits and the next header is sane too."""
        unpack = _RECORD[self.endian].unpack_from
        for depth in range(2):
            size = self.size
            if p == size and depth:
                return True
            if p + 16 > size:
                return False
            head = self.read_at(p, 16)
            if len(head) < 16:
                return False
            sec, frac, incl, orig = unpack(head)
            if frac >= div or incl > maxlen or orig < incl or orig > 16 * maxlen:
                return False
            if last_sec >= 0 and not (last_sec - RESYNC_WINDOW // 24 <= sec <= last_sec + RESYNC_WINDOW):
                return False
            if last_sec < 0 and not 0 < sec < 4_102_444_800:
                return False
            last_sec = sec
            p += 16 + incl
            if p > size:
                return False
        return True

    def _resync(self, pos: int, last_sec: int, maxlen: int, div: int) -> int:
        """Offset of the next plausible record header after a corrupt one at `pos`, or -1.

        Walks the file a window at a time; a cheap test of each offset's header comes first.
        """
        unpack = _RECORD[self.endian].unpack_from
        lo = last_sec - RESYNC_WINDOW // 24 if last_sec >= 0 else 1
        hi = last_sec + RESYNC_WINDOW if last_sec >= 0 else 4_102_444_799
        big = 16 * maxlen
        p = pos + 1
        while p < self.size - 15:
            buf = self.window_at(p)
            stop = min(len(buf), self.size - p) - 15  # offsets p + rel whose 16-byte header is in the window
            for rel in range(stop):
                sec, frac, incl, orig = unpack(buf, rel)
                if (frac < div and incl <= maxlen and incl <= orig <= big and lo <= sec <= hi
                        and self._plausible(p + rel, last_sec, maxlen, div)):
                    return p + rel
            p += max(stop, 1)
        return -1
