"""QGroundControl / MAVProxy telemetry logs: [8-byte big-endian µs timestamp][one MAVLink frame], repeated."""

from __future__ import annotations

import re
import struct
from collections.abc import Iterator

from mavscope.capture.base import LINKTYPE_MAVLINK_TLOG, Record
from mavscope.capture.reader import READER_BUGS, CaptureReader, make_record
from mavscope.notes import Note, note
from mavscope.wire import STX_V1, STX_V2, frame_size

TS_MIN = 946_684_800 * 1_000_000  # 2000-01-01 in microseconds since the Unix epoch
TS_MAX = 4_102_444_800 * 1_000_000  # 2100-01-01
RESYNC_BEHIND = 3_600 * 1_000_000  # how far (µs) before the last good entry a resynchronised one may lie
RESYNC_AHEAD = 86_400 * 1_000_000  # and how far after
LOOKAHEAD = 2 * (8 + 12 + 255 + 2 + 13)  # two entries: what deciding on an entry may look at
# Bytes a non-MAVLink entry may hold. MAVProxy logs what it could not parse (a SITL's console text, one byte
# an entry; pymavlink's BAD_DATA) as entries of their own; such an entry ends where the next timestamp starts.
TEXT_MAX = LOOKAHEAD - 16
SNIFF_TEXT = 32768  # bytes of such entries a tlog may start with (a SITL's boot messages)

_TS = struct.Struct(">Q")
_STX = re.compile(rb"[\xfd\xfe]")
STXS = (STX_V1, STX_V2)


def frame_length(buf: bytes, p: int, size: int) -> int:
    """Length of the MAVLink frame whose STX is at `p` (from its header), or -1 if not a frame start or cut."""
    return frame_size(buf, p) if p + 3 <= size else -1


def entry_end(buf: bytes, p: int, size: int, lo: int = TS_MIN, hi: int = TS_MAX) -> int:
    """End offset of a plausible, complete tlog entry at `p` (timestamp in [lo, hi)), or -1."""
    if p < 0 or p + 11 > size:
        return -1
    if not lo <= _TS.unpack_from(buf, p)[0] < hi:
        return -1
    flen = frame_length(buf, p + 8, size)
    if flen < 0 or p + 8 + flen > size:
        return -1
    return p + 8 + flen


def _followed(buf: bytes, p: int, size: int, lo: int, hi: int) -> bool:
    """Whether an entry ending at `p` is followed by a plausible entry, a cut one at the end, or the end."""
    if size - p < 11:  # the end, or an entry cut inside its header
        return True
    if not lo <= _TS.unpack_from(buf, p)[0] < hi or buf[p + 8] not in (STX_V1, STX_V2):
        return False
    return entry_end(buf, p, size, lo, hi) >= 0 or p + 8 + frame_length(buf, p + 8, size) > size


def find_entry(buf: bytes, size: int, start: int, last_ts: int = -1, limit: int | None = None) -> int:
    """Offset of the next plausible entry at or after `start`, followed by another one (or the end); or -1.

    With `last_ts` (µs) the entry's timestamp must lie near it. With `limit`, only entries that start
    before it are considered (a window of a longer file: the bytes from `limit` on are looked at only as
    the lookahead of an earlier entry).
    """
    lo, hi = TS_MIN, TS_MAX
    if last_ts >= 0:
        lo, hi = max(lo, last_ts - RESYNC_BEHIND), min(hi, last_ts + RESYNC_AHEAD)
    search = _STX.search
    q = start + 8
    stop = len(buf) if limit is None else limit + 8
    while True:
        m = search(buf, q, stop)
        if m is None:
            return -1
        q = m.start()
        p = q - 8
        end = entry_end(buf, p, size, lo, hi)
        if end >= 0 and _followed(buf, end, size, lo, hi):
            return p
        q += 1


def cut_at(buf: bytes, p: int, end: int, ts: int, size: int) -> int:
    """Where a whole entry starts inside the entry at `p` (timestamp `ts`), whose frame ends at `end` where no
    MAVLink entry starts (an STX after a timestamp near `ts`): the entry was cut short (a logger that lost
    bytes, a record cut to its first byte), and MAVLink's C parser, reading the file byte by byte, reads the
    entry inside it; -1 if none (or an entry follows: this one is whole)."""
    if end + 9 > size or (buf[end + 8] in STXS and near(_TS.unpack_from(buf, end)[0], ts)):
        return -1
    return find_entry(buf, size, p + 9, ts, end)


def near(ts: int, last_ts: int) -> bool:
    """Whether `ts` (µs) is a plausible entry timestamp after one at `last_ts` (-1: the first entry)."""
    if not TS_MIN <= ts < TS_MAX:
        return False
    return last_ts < 0 or last_ts - RESYNC_BEHIND <= ts <= last_ts + RESYNC_AHEAD


def text_entry_end(buf: bytes, p: int, stop: int, final: bool) -> int:
    """End of the entry at `p` whose bytes are not a MAVLink frame: the first offset after at least one byte
    where an entry with a timestamp near this one's starts, or the end of the file (`final`: `stop` is the
    end); within TEXT_MAX bytes and before `stop`; -1 if there is none."""
    if p + 9 > stop:
        return -1
    ts = _TS.unpack_from(buf, p)[0]
    ts_unpack = _TS.unpack_from
    last = min(stop - 8, p + 8 + TEXT_MAX)
    for q in range(p + 9, last + 1):
        if near(ts_unpack(buf, q)[0], ts):
            return q
    if final and stop - p - 8 <= TEXT_MAX:
        return stop
    return -1


def sniff_tlog(buf: bytes, size: int) -> bool:
    """Whether the file starts like a tlog: a plausible entry followed by another one (or the end).

    The file may start with entries of bytes that are not MAVLink (console text) when a MAVLink entry
    follows them within SNIFF_TEXT bytes. A damaged second entry is tolerated when a consistent entry
    follows within the next 4 KiB.
    """
    p = 0
    last_ts = -1
    while 0 <= p < SNIFF_TEXT and size - p >= 11 and buf[p + 8] not in (STX_V1, STX_V2):
        ts = _TS.unpack_from(buf, p)[0]
        if not near(ts, last_ts):
            return False
        last_ts = ts
        p = text_entry_end(buf, p, min(size, len(buf)), False)
    if not 0 <= p < SNIFF_TEXT:
        return False
    end = entry_end(buf, p, size)
    if end < 0:
        return False
    if _followed(buf, end, size, TS_MIN, TS_MAX):
        return True
    window = min(size, end + 4096)
    return find_entry(buf, window, end, _TS.unpack_from(buf, p)[0]) >= 0


class TlogReader(CaptureReader):
    """Reads a telemetry log entry by entry, a window of the file at a time; every record holds exactly one
    MAVLink frame. Record times lie in [2000, 2100) (entries with other timestamps are not entries), except
    a cut last entry's, which is None when its timestamp is not plausible.
    """

    kind = "tlog"

    def __init__(self, path: str) -> None:
        super().__init__(path)
        self._linktype = LINKTYPE_MAVLINK_TLOG

    def _find(self, buf: bytes, base: int, start: int, last_ts: int) -> tuple[int, bytes, int]:
        """find_entry over the file from offset `start`, a window at a time: (offset or -1, window, base).

        An entry is looked for in a window only where the window also holds its lookahead (the entry and
        the one after it), or where the window reaches the end of the file.
        """
        while True:
            if start < base or start + LOOKAHEAD >= base + len(buf) < self.size:
                buf, base = self.window_at(start, 2 * LOOKAHEAD), start
            size = self.size
            final = base + len(buf) >= size
            limit = len(buf) if final else len(buf) - LOOKAHEAD
            q = find_entry(buf, size - base if final else len(buf), start - base, last_ts, limit)
            if q >= 0:
                return base + q, buf, base
            if final:
                return -1, buf, base
            start = base + limit

    def _records(self) -> Iterator[Record]:
        ts_unpack = _TS.unpack_from
        size_of = frame_size
        tuple_new = tuple.__new__
        R = Record
        LT = LINKTYPE_MAVLINK_TLOG
        lo_ts, hi_ts, behind, ahead, stxs = TS_MIN, TS_MAX, RESYNC_BEHIND, RESYNC_AHEAD, STXS
        n = 0
        pos = base = 0
        buf = b""
        last_ts = -1
        pending: tuple[Note, ...] = ()
        try:
            buf = self.window_at(0, 2 * LOOKAHEAD)
            size = self.size
            while pos < size:
                # the common case, kept tight: complete entries whose frames fit the window
                p = pos - base
                blen = len(buf)
                last = blen - LOOKAHEAD if base + blen < size else blen - 11  # entries decidable in the window
                # (each entry's timestamp is read once: the test that an entry starts where one ends reads the
                # next one's, which is then its own, in range; near() inlined)
                ts = ts_unpack(buf, p)[0] if p <= last else 0
                while p <= last and lo_ts <= ts < hi_ts:
                    flen = size_of(buf, p + 8)
                    if flen < 0:
                        break
                    end = p + 8 + flen
                    if end > blen:
                        break
                    if end + 9 <= blen:
                        nts = ts_unpack(buf, end)[0]
                        if buf[end + 8] not in stxs or not (lo_ts <= nts < hi_ts and ts - behind <= nts <= ts + ahead):
                            break  # no entry starts where it ends: the slow path looks for one inside it
                    else:  # (the file's last entry: the loop ends with it)
                        nts = 0
                    n += 1
                    last_ts = ts
                    yield tuple_new(R, (n, ts / 1e6, LT, buf[p + 8:end], base + p + 8, end - p - 8, pending))
                    pending = ()
                    p = end
                    ts = nts
                    if not n & 1023:
                        self.position = base + p
                pos = base + p
                self.position = pos
                if pos >= size:
                    break
                if p + LOOKAHEAD > len(buf) and base + len(buf) < size:  # near the window's end: read on
                    buf, base = self.window_at(pos, 2 * LOOKAHEAD), pos
                    size = self.size
                    continue
                if pos + 9 <= size and buf[p + 8] not in (STX_V1, STX_V2) and near(ts_unpack(buf, p)[0], last_ts):
                    blen = len(buf)
                    q = text_entry_end(buf, p, blen, base + blen >= size)
                    if q >= 0:  # an entry of bytes that are not MAVLink: the dissector says what they are
                        ts = ts_unpack(buf, p)[0]
                        n += 1
                        last_ts = ts
                        yield tuple_new(R, (n, ts / 1e6, LT, buf[p + 8:q], base + p + 8, q - p - 8, pending))
                        pending = ()
                        pos = base + q
                        self.position = pos
                        continue
                if pos + 11 <= size:
                    ts = ts_unpack(buf, p)[0]
                    flen = frame_size(buf, p + 8)
                    end = p + 8 + flen if flen >= 0 else -1
                    if end >= 0 and TS_MIN <= ts < TS_MAX:
                        q = cut_at(buf, p, end, ts, size - base if base + len(buf) >= size else len(buf))
                        if q >= 0:  # cut short where a whole entry starts inside it
                            n += 1
                            last_ts = ts
                            pending += (note("record-truncated", f"tlog entry at offset {pos} has {q - p - 8} of "
                                             f"{flen} frame bytes: the entry at offset {base + q} starts inside it",
                                             pos),)
                            yield tuple_new(R, (n, ts / 1e6, LT, buf[p + 8:q], base + p + 8, flen, pending))
                            pending = ()
                            pos = base + q
                            self.position = pos
                            continue
                        if base + end <= size:
                            n += 1
                            last_ts = ts
                            self.position = base + end
                            yield tuple_new(R, (n, ts / 1e6, LT, buf[p + 8:end], base + p + 8, end - p - 8, pending))
                            pending = ()
                            pos = base + end
                            continue
                        q, buf, base = self._find(buf, base, pos + 1, last_ts)
                        size = self.size
                        if q < 0:  # a cut last entry
                            n += 1
                            self.position = size
                            pending += (note("record-truncated",
                                             f"tlog entry at offset {pos} has {size - pos - 8} of {flen} "
                                             "frame bytes: file cut short", pos),)
                            pending += self.shrink_notes()
                            yield make_record(n, ts / 1e6, LT, self.read_at(pos + 8, size - pos - 8), pos + 8, flen,
                                              pending)
                            return
                        pending += (note("capture-garbage",
                                         f"broken tlog entry at offset {pos}: {q - pos} bytes skipped", pos),)
                        pos = q
                        continue
                q, buf, base = self._find(buf, base, pos + 1, last_ts)
                size = self.size
                if q < 0:
                    if size - pos < 11:  # too short for an entry header: a cut last entry
                        stamp = self.read_at(pos, 8)
                        ts = ts_unpack(stamp)[0] if len(stamp) == 8 else -1
                        n += 1
                        self.position = size
                        pending += (note("record-truncated", f"file ends {size - pos} bytes into a tlog entry", pos),)
                        pending += self.shrink_notes()
                        start = min(pos + 8, size)
                        t = ts / 1e6 if TS_MIN <= ts < TS_MAX else None
                        yield make_record(n, t, LT, self.read_at(start, size - start), start, size - start, pending)
                        return
                    pending += (note("capture-garbage", f"broken tlog entry at offset {pos}; "
                                     f"no later entry found, {size - pos} bytes skipped", pos),)
                    break
                pending += (note("capture-garbage",
                                 f"broken tlog entry at offset {pos}: {q - pos} bytes skipped", pos),)
                pos = q
            pending += self.shrink_notes()
            self.position = size = self.size
            if pending:
                n += 1
                yield make_record(n, None, LT, b"", min(pos + 8, size), 0, pending)
        except READER_BUGS as exc:
            yield self.failure(n + 1, pos, exc, pending)
