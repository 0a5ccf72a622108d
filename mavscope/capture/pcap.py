"""Classic libpcap files: both byte orders, microsecond and nanosecond timestamps."""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator

from mavscope.capture.base import Record
from mavscope.capture.reader import READER_BUGS, CaptureReader, make_record
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
    """Reads a classic pcap file record by record from a memory mapping."""

    kind = "pcap"

    def __init__(self, path: str | os.PathLike[str]) -> None:
        super().__init__(path)
        buf = self._buf
        self.endian = sniff_pcap(bytes(buf[:4])) or "<"
        magic = struct.unpack_from(self.endian + "I", buf)[0] if self.size >= 4 else MAGIC_US
        self.nanosecond = magic == MAGIC_NS
        self.snaplen = 0
        self.linktype = 1
        self.version = (2, 4)
        self._header_ok = self.size >= 24
        if self._header_ok:
            _, vmaj, vmin, _, _, snaplen, network = _GLOBAL[self.endian].unpack_from(buf, 0)
            self.version = (vmaj, vmin)
            self.snaplen = snaplen
            self.linktype = network & 0xFFFF  # upper bits may carry FCS information
        self._linktype = self.linktype

    def _records(self) -> Iterator[Record]:
        buf = self._buf
        size = self.size
        linktype = self.linktype
        if not self._header_ok:
            self.position = size
            if size:
                yield make_record(1, None, linktype, b"", 0, 0, (
                    note("record-truncated", f"file ends {size} bytes into the 24-byte pcap header", 0),))
            return
        unpack = _RECORD[self.endian].unpack_from
        div = 1_000_000_000 if self.nanosecond else 1_000_000
        maxlen = max(self.snaplen, MIN_MAX_RECORD)
        tuple_new = tuple.__new__
        R = Record
        n = 0
        pos = 24
        last_sec = _RECORD[self.endian].unpack_from(buf, 24)[0] if size >= 40 else -1
        pending: tuple[Note, ...] = ()
        last = size - 16
        try:
            while True:
                # the common case, kept tight: complete, unsnapped records while there is nothing to report
                if not pending:
                    while pos <= last:
                        sec, frac, incl, orig = unpack(buf, pos)
                        start = pos + 16
                        end = start + incl
                        if end > size or incl > maxlen or orig != incl:
                            break
                        n += 1
                        yield tuple_new(R, (n, sec + frac / div, linktype, buf[start:end], start, orig, ()))
                        pos = end
                        if not n & 1023:
                            self.position = pos
                            last_sec = sec  # resynchronisation looks for timestamps near this one
                self.position = pos
                if pos > last:
                    if pos < size:
                        n += 1
                        pending += (note("record-truncated",
                                         f"file ends {size - pos} bytes into a 16-byte record header at offset {pos}",
                                         pos),)
                        self.position = size
                        yield make_record(n, None, linktype, b"", pos, 0, pending)
                    elif pending:
                        n += 1
                        yield make_record(n, None, linktype, b"", pos, 0, pending)
                    return
                sec, frac, incl, orig = unpack(buf, pos)
                if incl > maxlen:
                    found = self._resync(pos, last_sec, maxlen, div)
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
                yield make_record(n, sec + frac / div, linktype, buf[start:end], start, orig, pending)
                pending = ()
                pos = end
        except READER_BUGS as exc:
            yield self.failure(n + 1, pos, exc, pending)

    def _plausible(self, p: int, last_sec: int, maxlen: int, div: int) -> bool:
        """Whether a record header at `p` looks sane, its record fits and the next header is sane too."""
        size = self.size
        unpack = _RECORD[self.endian].unpack_from
        for depth in range(2):
            if p == size and depth:
                return True
            if p + 16 > size:
                return False
            sec, frac, incl, orig = unpack(self._buf, p)
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
        """Offset of the next plausible record header after a corrupt one at `pos`, or -1."""
        for p in range(pos + 1, self.size - 15):
            if self._plausible(p, last_sec, maxlen, div):
                return p
        return -1
