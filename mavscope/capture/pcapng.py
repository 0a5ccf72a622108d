"""pcapng files: sections in either byte order, several interfaces, EPB, SPB and obsolete packet blocks."""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator

from mavscope.capture.base import Record
from mavscope.capture.reader import READER_BUGS, CaptureReader, make_record
from mavscope.notes import Note, note

BT_SHB = 0x0A0D0D0A
BT_IDB = 0x00000001
BT_OPB = 0x00000002  # obsolete Packet Block
BT_SPB = 0x00000003
BT_NRB = 0x00000004
BT_ISB = 0x00000005
BT_EPB = 0x00000006
BT_DSB = 0x0000000A
BYTE_ORDER_MAGIC = 0x1A2B3C4D
OPT_ENDOFOPT = 0
OPT_IF_TSRESOL = 9
OPT_IF_TSOFFSET = 14
CALENDAR_END = 253_402_300_800.0  # 10000-01-01: the first time a calendar date (datetime) cannot show
MAX_BLOCK = 16 * 1024 * 1024  # a longer block is taken as a corrupt length (libpcap uses the same bound)
_KNOWN = frozenset((BT_SHB, BT_IDB, BT_OPB, BT_SPB, BT_NRB, BT_ISB, BT_EPB, BT_DSB, 0x80000001, 7, 8, 9, 0xB, 0xC))

_U32 = {e: struct.Struct(e + "I") for e in "<>"}
_BLOCK = {e: struct.Struct(e + "II") for e in "<>"}
_IDB = {e: struct.Struct(e + "HHI") for e in "<>"}
_EPB = {e: struct.Struct(e + "IIIII") for e in "<>"}
_FAST = {e: struct.Struct(e + "IIIIIII") for e in "<>"}  # block type and length, then the EPB fields
_OPB = {e: struct.Struct(e + "HHIIII") for e in "<>"}
_OPT = {e: struct.Struct(e + "HH") for e in "<>"}
_I64 = {e: struct.Struct(e + "q") for e in "<>"}


def sniff_pcapng(head: bytes) -> str | None:
    """The byte order of the first section if `head` starts a pcapng file, else None."""
    if len(head) < 12 or head[:4] != b"\x0a\x0d\x0d\x0a":
        return None
    for e in "<>":
        if _U32[e].unpack_from(head, 8)[0] == BYTE_ORDER_MAGIC:
            return e
    return None


class Interface:
    """What an Interface Description Block says: link type, snap length and timestamp scale."""

    __slots__ = ("linktype", "snaplen", "units", "tsoffset")

    def __init__(self, linktype: int, snaplen: int, units: int = 1_000_000, tsoffset: int = 0) -> None:
        self.linktype = linktype
        self.snaplen = snaplen
        self.units = units  # timestamp ticks per second
        self.tsoffset = tsoffset  # seconds added to every timestamp

    def __repr__(self) -> str:
        return f"Interface(linktype={self.linktype}, snaplen={self.snaplen}, units={self.units})"


def _time_note(t: float, iface: int, ifc: Interface, offset: int) -> Note:
    return note("time-out-of-range", f"packet time {t:.6g} s since 1970 (interface {iface}: if_tsoffset "
                f"{ifc.tsoffset} s, {ifc.units} ticks/s)", offset)


class PcapngReader(CaptureReader):
    """Reads a pcapng file block by block, a window of the file at a time.

    Record times are `ticks / units + if_tsoffset` as the interface says: finite, but anywhere in about
    [-2**63, 2**64 + 2**63] seconds for a hostile file (a negative or huge offset, a 1 s resolution);
    SPB records have none (None).
    """

    kind = "pcapng"

    def __init__(self, path: str | os.PathLike[str]) -> None:
        super().__init__(path)
        self.interfaces: list[Interface] = []
        self._linktype = 1

    def _header(self, buf: bytes, base: int, q: int, endian: str) -> tuple[int, int, str] | None:
        """(type, total length, byte order) of a block header at buf[q] (file offset base + q) with a sane
        length, or None. The block itself may run past the end of the file or of `buf`.
        """
        if base + q + 12 > self.size or q + 12 > len(buf):
            return None
        if buf[q:q + 4] == b"\x0a\x0d\x0d\x0a":
            e = sniff_pcapng(buf[q:q + 12])
            if e is None:
                return None
            endian = e
        btype, blen = _BLOCK[endian].unpack_from(buf, q)
        if blen < 12 or blen & 3 or blen > MAX_BLOCK or (btype == BT_SHB and blen < 28):
            return None
        return btype, blen, endian

    def _block_at(self, buf: bytes, base: int, q: int, endian: str) -> tuple[int, int, str] | None:
        """(type, total length, byte order) of a complete block at buf[q] whose trailer matches, or None.

        The trailer is read from the file when it lies past the end of `buf`.
        """
        found = self._header(buf, base, q, endian)
        if found is None:
            return None
        btype, blen, endian = found
        if base + q + blen > self.size:
            return None
        t = q + blen - 4
        if t + 4 <= len(buf):
            trailer = _U32[endian].unpack_from(buf, t)[0]
        else:
            tail = self.read_at(base + t, 4)
            if len(tail) < 4:
                return None
            trailer = _U32[endian].unpack_from(tail)[0]
        return found if trailer == blen else None

    def _resync(self, p: int, endian: str) -> int:
        """Offset of the next sane block of a known type after `p`, or -1 (the file a window at a time)."""
        q = p + 1
        while q < self.size - 11:
            buf = self.window_at(q)
            stop = min(len(buf), self.size - q) - 11  # offsets q + rel whose 12-byte header is in the window
            for rel in range(stop):
                found = self._block_at(buf, q, rel, endian)
                if found is not None and found[0] in _KNOWN:
                    return q + rel
            q += max(stop, 1)
        return -1

    def _records(self) -> Iterator[Record]:
        ifaces = self.interfaces
        tuple_new = tuple.__new__
        R = Record
        n = 0
        pos = base = 0
        buf = b""
        pending: tuple[Note, ...] = ()
        e = "<"
        try:
            buf = self.window_at(0)
            size = self.size
            e = sniff_pcapng(buf[:12]) or "<"
            fast = _FAST[e].unpack_from
            u32 = _U32[e].unpack_from
            while pos < size:
                # the common case, kept tight: an Enhanced Packet Block in the window, of a known interface
                rel = pos - base
                if rel + 28 <= len(buf):
                    btype, blen, iface, hi, lo, caplen, orig = fast(buf, rel)
                    if (btype == BT_EPB and iface < len(ifaces) and caplen <= blen - 32 and blen <= MAX_BLOCK
                            and not blen & 3 and rel + blen <= len(buf) and u32(buf, rel + blen - 4)[0] == blen):
                        start = rel + 28
                        ifc = ifaces[iface]
                        n += 1
                        notes = pending
                        if orig < caplen:
                            orig = caplen
                        elif orig > caplen:
                            notes += (note("record-snapped", f"{caplen} of {orig} bytes captured", base + start),)
                        t = ((hi << 32) | lo) / ifc.units + ifc.tsoffset
                        if not 0.0 <= t < CALENDAR_END:
                            notes += (_time_note(t, iface, ifc, base + rel),)
                        yield tuple_new(R, (n, t, ifc.linktype, buf[start:start + caplen], base + start, orig, notes))
                        pending = ()
                        pos += blen
                        if not n & 1023:
                            self.position = pos
                        continue
                self.position = pos
                have = base + len(buf)  # the window holds the file's bytes up to here
                if pos + 12 > size:
                    pending += (note("record-truncated", f"file ends {size - pos} bytes into a block header", pos),)
                    break
                if pos + 12 > have:
                    buf, base = self.window_at(pos), pos
                    size = self.size
                    continue
                rel = pos - base
                head = self._header(buf, base, rel, e)
                if head is not None:
                    need = max(head[1], 28)  # a short packet block is still read as one (its fields run on)
                    if pos + need > have and have < size and pos + head[1] <= size:
                        buf, base = self.window_at(pos, need), pos  # read the whole block
                        size = self.size
                        continue
                found = self._block_at(buf, base, rel, e)
                if found is None:
                    q = self._resync(pos, e)
                    size = self.size
                    if q >= 0:
                        pending += (note("capture-garbage", f"corrupt block at offset {pos}: {q - pos} bytes skipped",
                                         pos),)
                        pos = q
                        continue
                    if head is not None and pos + head[1] > size:
                        # a sane header whose block runs past the end, and nothing after: the file was cut short
                        btype, blen = head[0], head[1]
                        cut = note("record-truncated",
                                   f"block at offset {pos} has {size - pos} of {blen} bytes: file cut short", pos)
                        rec = None
                        if btype in (BT_EPB, BT_OPB, BT_SPB):
                            buf, base = self.window_at(pos, size - pos), pos
                            size = self.size
                            rec = self._packet(buf, base, 0, btype, blen, e, n + 1)
                        if rec is not None:
                            n += 1
                            self.position = size
                            yield rec._replace(notes=pending + rec.notes + (cut,))
                            pending = ()
                        else:
                            pending += (cut,)
                    else:
                        pending += (note("capture-garbage", f"corrupt block at offset {pos}; no later block found, "
                                         f"{size - pos} bytes skipped", pos),)
                    pos = size
                    break
                btype, blen, e2 = found
                if btype in (BT_EPB, BT_OPB, BT_SPB):
                    rec = self._packet(buf, base, rel, btype, blen, e, n + 1)
                    if rec is None:
                        pending += (note("capture-garbage",
                                         f"packet block at offset {pos} refers to an undefined interface", pos),)
                    else:
                        n += 1
                        yield rec._replace(notes=pending + rec.notes)
                        pending = ()
                elif btype == BT_SHB:
                    if e2 != e:
                        e = e2
                        fast = _FAST[e].unpack_from
                        u32 = _U32[e].unpack_from
                    ifaces.clear()
                elif btype == BT_IDB:
                    ifaces.append(self._interface(buf, rel, blen, e))
                pos += blen
            pending += self.shrink_notes()
            self.position = size = self.size
            if pending:
                n += 1
                lt = ifaces[0].linktype if ifaces else 1
                yield make_record(n, None, lt, b"", min(pos, size), 0, pending)
        except READER_BUGS as exc:
            yield self.failure(n + 1, pos, exc, pending)

    def _packet(self, buf: bytes, base: int, pos: int, btype: int, blen: int, e: str, number: int) -> Record | None:
        """The Record of a packet block at buf[pos] (possibly cut short by the end of the file); None without
        interface. `buf` holds the block, or the file's bytes to its end."""
        ifaces = self.interfaces
        notes: tuple[Note, ...] = ()
        size = self.size - base  # where the file ends, as an index into buf
        if btype == BT_SPB:
            if not ifaces or pos + 12 > size:
                return None
            ifc = ifaces[0]
            orig = _U32[e].unpack_from(buf, pos + 8)[0]
            start = pos + 12
            room = min(blen - 16, size - start)
            caplen = max(min(orig, room), 0)
            if ifc.snaplen:
                caplen = min(caplen, ifc.snaplen)
            t = None
        else:
            if pos + 28 > size:
                return None
            if btype == BT_EPB:
                iface, hi, lo, caplen, orig = _EPB[e].unpack_from(buf, pos + 8)
            else:
                iface, _drops, hi, lo, caplen, orig = _OPB[e].unpack_from(buf, pos + 8)
            if iface >= len(ifaces):
                return None
            ifc = ifaces[iface]
            start = pos + 28
            room = min(blen - 32, size - start)
            if caplen > room:
                if pos + blen <= size:
                    notes += (note("record-truncated", f"packet block at offset {base + pos} claims {caplen} "
                                   f"captured bytes, holds {room}", base + pos),)
                caplen = max(room, 0)
            t = ((hi << 32) | lo) / ifc.units + ifc.tsoffset
            if not 0.0 <= t < CALENDAR_END:
                notes += (_time_note(t, iface, ifc, base + pos),)
        data = buf[start:start + caplen]
        if orig < caplen:
            orig = caplen
        elif orig > caplen:
            notes += (note("record-snapped", f"{caplen} of {orig} bytes captured", base + start),)
        return make_record(number, t, ifc.linktype, data, base + start, orig, notes)

    def _interface(self, buf: bytes, pos: int, blen: int, e: str) -> Interface:
        """Decode an Interface Description Block at buf[pos] and its timestamp options."""
        linktype, _reserved, snaplen = _IDB[e].unpack_from(buf, pos + 8) if blen >= 20 else (1, 0, 0)
        ifc = Interface(linktype, snaplen)
        p, end = pos + 16, pos + blen - 4
        opt = _OPT[e].unpack_from
        while p + 4 <= end:
            code, length = opt(buf, p)
            if code == OPT_ENDOFOPT:
                break
            v = p + 4
            if v + length > end:
                break
            if code == OPT_IF_TSRESOL and length >= 1:
                r = buf[v]
                exp = r & 0x7F
                if exp <= 63:  # a larger exponent cannot be represented; keep the default
                    ifc.units = (2 ** exp) if r & 0x80 else (10 ** exp)
            elif code == OPT_IF_TSOFFSET and length >= 8:
                ifc.tsoffset = _I64[e].unpack_from(buf, v)[0]
            p = v + ((length + 3) & ~3)
        if ifc.units == 0:
            ifc.units = 1_000_000
        return ifc
