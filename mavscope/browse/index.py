"""A compact index of every frame of a capture, for browsing a million frames (the TUI's model).

Walking the pipeline once, `FrameIndex` keeps per frame only a row of numbers in parallel `array`
columns (record, index, time, endpoints, header fields, verdict codes, where the bytes are), about 45
bytes a frame, instead of a `Frame` (a tuple of 23 fields plus its bytes: about 500). A frame is
rebuilt on demand from its row and its bytes, and the decoded details (fields, detail tree, summary)
of recently viewed frames are kept in an LRU, as toolong and termshark do.

Where the bytes come from (measured on a 1.1M-frame pcap; see docs/tui.md):
- A frame that lies contiguous in the capture file (every datagram frame of a pcap/pcapng, every tlog
  entry, most TCP and raw-stream frames) is re-read from the file (`os.pread`) at `Frame.offset`: 10
  bytes of index (offset and length), no copy of the bytes. The build checks that the file holds exactly
  the frame's bytes there.
- A frame whose bytes are split across records (TCP segments, raw-stream chunks) or that has no file
  (a live source) keeps its bytes in a side table.
What the pipeline said that the bytes cannot tell again (notes such as skipped bytes before the frame,
the records a reassembled frame spans, the security layer's verdicts) is kept exactly: notes and spans
in sparse tables, security verdicts interned (a signed capture has a handful of distinct ones).

The index is filled by one thread (`build`, or with the native engine `browse.native.native_build`, which
appends the walker's chunks of clean frames in bulk through `extend`) while another reads it: rows below
`len(index)` are complete and never change. No Textual here: the TUI drives `build` from a worker.
"""

from __future__ import annotations

import os
import threading
from array import array
from bisect import bisect_left
from collections.abc import Callable, Collection, Iterable, Iterator
from typing import Any

from mavscope.browse.rows import LRU, Detail, Progress, Row
from mavscope.capture.reader import FileBytes, open_file
from mavscope.endpoint import Endpoint
from mavscope.fields.summary import summary_info
from mavscope.fields.tree import frame_items
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus, Frame, Security, decode_payload, frame_number
from mavscope.mavlink.framing import build_frame
from mavscope.notes import Note, is_capture_damage, problem_line
from mavscope.pipeline.dissect import Anomaly
from mavscope.wire import HEADER_V1, HEADER_V2, STX_V2

CRC_CODES: tuple[CrcStatus, ...] = (CrcStatus.OK, CrcStatus.BAD, CrcStatus.UNCHECKED, CrcStatus.TRUNCATED)
_CRC_CODE = {s: i for i, s in enumerate(CRC_CODES)}
NO_OFFSET = -1  # offset column: Frame.offset is None

PROGRESS_EVERY = 8192  # items between progress callbacks (and cancellation checks)


def _bytes_of(a: Any) -> memoryview:
    """A numpy array's bytes, for array.frombytes (which takes a buffer of bytes only)."""
    import numpy as np

    return memoryview(np.ascontiguousarray(a)).cast("B")  # type: ignore[arg-type]


class FrameIndex:
    """Every frame of one capture as a compact row; frames and their details rebuilt on demand.

    `path` is the capture file the frames came from (None for a live source: every frame's bytes are
    then kept). `limit` bounds the number of rows for a live source: older rows are dropped in blocks
    so memory stays bounded. Row numbers never change: rows `first` .. `end - 1` are held, and asking
    for a dropped row raises `IndexError`, so a number taken before a drop never names another frame.
    """

    def __init__(self, dialect: Dialect, path: str | os.PathLike[str] | None = None,
                 cache_size: int = 2048) -> None:
        self.dialect = dialect
        self.path = os.fspath(path) if path is not None else None
        self._bytes: FileBytes | None = None  # the capture's bytes, read (not mapped: the file may shrink)
        if self.path is not None:
            self._bytes = FileBytes(open_file(self.path)[1])
        # columns, one entry per frame
        self._record = array("I")
        self._index = array("H")
        self._time = array("d")  # NaN where the capture has no time
        self._transport = array("B")
        self._src = array("I")
        self._dst = array("I")
        self._offset = array("q")  # Frame.offset (NO_OFFSET for None); the bytes are there unless in _raw
        self._rawlen = array("H")
        self._crc = array("B")  # index into CRC_CODES
        self._iflags = array("B")
        self._sysid = array("B")
        self._compid = array("B")
        self._seq = array("B")
        self._msgid = array("I")
        self._security = array("I")  # index into self._securities (0: None)
        # interned strings and verdicts
        self._transports: list[str] = []
        self._transport_ids: dict[str, int] = {}
        self._endpoints: list[Endpoint | None] = [None]
        self._endpoint_ids: dict[Endpoint | None, int] = {None: 0}
        self._securities: list[Security | None] = [None]
        self._security_ids: dict[Security, int] = {}
        # sparse side tables
        self._raw: dict[int, bytes] = {}
        self._notes: dict[int, tuple[Note, ...]] = {}
        self._spans: dict[int, tuple[int, ...]] = {}
        # Frames come in the order the pipeline completes them, not always in record order: a TCP hole
        # holds bytes back, and the frames they complete come out later, each its own earlier record's.
        # Such a "late" row (its record below the highest before it) is kept here, sparse: its position ->
        # the highest record before it (so that column, the running maximum, is sorted: find_record
        # bisects it), and each record's first late position.
        self._late: dict[int, int] = {}
        self._late_first: dict[int, int] = {}
        self._top = 0  # the highest record of the rows appended so far
        self.anomalies: list[Anomaly] = []
        self._count = 0
        self.first = 0  # the oldest row held (rows dropped from the front so far, in a bounded live index)
        self.limit: int | None = None  # keep at most this many rows (None: all)
        self.lock = threading.RLock()  # held while rows are read or dropped
        self._details = LRU(cache_size)
        self.progress = Progress(0, 0, 0, False)
        self.first_time: float | None = None  # time of the first frame
        self.t0: float | None = None  # time of the capture's first record, where the caller knows it

    # --- building -----------------------------------------------------------------------------

    def build(
        self,
        items: Iterable[Frame | Anomaly],
        *,
        position: Callable[[], int] = lambda: 0,
        total: int = 0,
        on_progress: Callable[[Progress], object] | None = None,
        cancelled: Callable[[], bool] = lambda: False,
        every: int = PROGRESS_EVERY,
    ) -> Progress:
        """Index every frame of `items` (the pipeline's output); returns the final progress.

        `position()` tells how far into the capture the reader is (bytes, of `total`); `on_progress`
        is called every `every` items and at the end; `cancelled()` is checked as often, and a
        cancelled build stops there (its rows stay valid).
        """
        add = self.add
        n = 0
        first_batch = min(every, 256)  # the first rows go out quickly so a UI can show them at once
        for item in items:
            if type(item) is Anomaly:
                self.anomalies.append(item)
            else:
                add(item)
            n += 1
            if n == first_batch or not n % every:
                self.progress = Progress(self._count, position(), total, False)
                if on_progress is not None:
                    on_progress(self.progress)
                if cancelled():
                    self.progress = Progress(self._count, position(), total, False, True)
                    break
        else:
            self.progress = Progress(self._count, total, total, True)
        if on_progress is not None:
            on_progress(self.progress)
        return self.progress

    def add(self, frame: Frame) -> None:
        """Append one frame (from the building thread)."""
        if self.limit is not None and self._count >= self.limit:
            self.trim(max(1, self.limit // 4))
        i = self._count
        raw = frame.raw
        off = frame.offset
        if off is None or off < 0 or self._bytes is None or self._bytes.get(off, len(raw)) != raw:
            self._raw[i] = raw  # not in the file as one piece: keep the bytes
        if off is None:
            off = NO_OFFSET
        t = frame.time
        if t is not None and self.first_time is None:
            self.first_time = t
        tr = self._transport_ids.get(frame.transport)
        if tr is None:
            tr = self._transport_ids[frame.transport] = len(self._transports)
            self._transports.append(frame.transport)
        eps = self._endpoint_ids
        src = eps.get(frame.src)
        if src is None:
            src = eps[frame.src] = len(self._endpoints)
            self._endpoints.append(frame.src)
        dst = eps.get(frame.dst)
        if dst is None:
            dst = eps[frame.dst] = len(self._endpoints)
            self._endpoints.append(frame.dst)
        sec = frame.security
        sid = 0 if sec is None else self._security_id(sec)
        if frame.notes:
            self._notes[i] = frame.notes
        if frame.span is not None:
            self._spans[i] = frame.span
        if frame.record < self._top:
            self._late_row(i, frame.record)
        else:
            self._top = frame.record
        self._record.append(frame.record)
        self._index.append(min(frame.index, 0xFFFF))
        self._time.append(t if t is not None else float("nan"))
        self._transport.append(tr)
        self._src.append(src)
        self._dst.append(dst)
        self._offset.append(off)
        self._rawlen.append(len(raw))
        self._crc.append(_CRC_CODE[frame.crc_status])
        self._iflags.append(frame.incompat_flags)
        self._sysid.append(frame.sysid)
        self._compid.append(frame.compid)
        self._seq.append(frame.seq)
        self._msgid.append(frame.msgid)
        self._security.append(sid)
        self._count = i + 1  # published last: readers only look below _count

    def endpoint_id(self, ep: Endpoint | None) -> int:
        """The interned id of `ep` (a new one when first seen)."""
        eps = self._endpoint_ids
        got = eps.get(ep)
        if got is None:
            got = eps[ep] = len(self._endpoints)
            self._endpoints.append(ep)
        return got

    def extend(self, chunk: Any, ends: Any, transports: tuple[str, ...]) -> None:
        """Append a native chunk of clean frames (mavscope.native.index: numpy columns, `ends` mapping its
        endpoint ids + 1 to this index's, None when they are the same; `transports` its transport codes to
        names), as `add` would
        append each frame: CRC ok, no note, span or security verdict, the bytes at their offset."""
        n = chunk.n
        if self.limit is not None:  # a bounded index is live, never native: keep add's trimming
            raise ValueError("extend: a bounded index")
        import numpy as np  # only the native build, which has numpy, comes here

        codes = np.flatnonzero(np.bincount(chunk.transport, minlength=len(transports)))
        tmap = np.zeros(len(transports), np.uint8)
        for code in codes.tolist():
            name = transports[code]
            tr = self._transport_ids.get(name)
            if tr is None:
                tr = self._transport_ids[name] = len(self._transports)
                self._transports.append(name)
            tmap[code] = tr
        if self.first_time is None and chunk.time_ok.any():
            self.first_time = float(chunk.time[int(np.argmax(chunk.time_ok))])
        records = chunk.record.astype(np.uint32)
        if n:
            top = np.maximum.accumulate(np.concatenate([np.array([self._top], np.int64), chunk.record]))
            for j in np.flatnonzero(chunk.record < top[:-1]).tolist():  # late rows (none, unless after a hole)
                self._late_row(self._count + j, int(chunk.record[j]), int(top[j]))
            self._top = int(top[-1])
        self._record.frombytes(_bytes_of(records))
        self._index.frombytes(_bytes_of(np.minimum(chunk.index, 0xFFFF).astype(np.uint16)))
        timed = chunk.time_ok.all()
        self._time.frombytes(_bytes_of(chunk.time if timed else np.where(chunk.time_ok != 0, chunk.time, np.nan)))
        self._transport.frombytes(_bytes_of(tmap[chunk.transport]) if len(codes) > 1 or tmap[codes[0]] else bytes(n))
        if ends is None:  # the walker's ids are this index's, less one (no gather)
            self._src.frombytes(_bytes_of((chunk.src + 1).view(np.uint32)))
            self._dst.frombytes(_bytes_of((chunk.dst + 1).view(np.uint32)))
        else:
            self._src.frombytes(_bytes_of(ends[chunk.src + 1]))
            self._dst.frombytes(_bytes_of(ends[chunk.dst + 1]))
        self._offset.frombytes(_bytes_of(chunk.offset))
        self._rawlen.frombytes(_bytes_of(chunk.size))
        self._crc.frombytes(bytes(n))  # CRC_CODES[0]: ok
        self._iflags.frombytes(_bytes_of(chunk.iflags))
        self._sysid.frombytes(_bytes_of(chunk.sysid))
        self._compid.frombytes(_bytes_of(chunk.compid))
        self._seq.frombytes(_bytes_of(chunk.seq))
        self._msgid.frombytes(_bytes_of(chunk.msgid))
        self._security.frombytes(bytes(4 * n))  # no verdict
        self._count += n  # published last: readers only look below _count

    def _late_row(self, i: int, record: int, top: int | None = None) -> None:
        """Row position `i` holds a frame of `record`, below the highest record before it (`top`, default
        the highest so far): remember it for find_record."""
        self._late[i] = self._top if top is None else top
        self._late_first.setdefault(record, i)

    def _security_id(self, sec: Security) -> int:
        sid = self._security_ids.get(sec)
        if sid is None:
            sid = self._security_ids[sec] = len(self._securities)
            self._securities.append(sec)
        return sid

    def rejudge(self, judge: Callable[[Iterable[Frame]], Iterable[Frame | Anomaly]],
                strip: Collection[str]) -> int:
        """Judge every row held again, oldest first, after the key material changed (live capture):
        each frame loses its verdicts and the notes whose codes are in `strip`, goes through `judge` (a
        security stage's `run`, one frame out per frame in), and takes what comes out. Call it from
        the thread that adds rows. Returns the number of rows judged."""
        rows = self.rows()

        def bare() -> Iterator[Frame]:
            for n in rows:
                f = self.frame(n)
                yield f._replace(security=None, notes=tuple(x for x in f.notes if x.code not in strip))

        done = 0
        for n, f in zip(rows, judge(bare())):
            sid = 0 if f.security is None else self._security_id(f.security)  # type: ignore[union-attr]
            with self.lock:
                i = self._position(n)
                self._security[i] = sid
                if f.notes:
                    self._notes[i] = f.notes
                else:
                    self._notes.pop(i, None)
            done += 1
        self._details.clear()
        return done

    def trim(self, n: int) -> None:
        """Drop the oldest `n` rows (their numbers are not reused: `first` moves up by `n`)."""
        with self.lock:
            n = min(n, self._count)
            for col in (self._record, self._index, self._time, self._transport, self._src, self._dst, self._offset,
                        self._rawlen, self._crc, self._iflags, self._sysid, self._compid, self._seq, self._msgid,
                        self._security):
                del col[:n]
            self._raw = {k - n: v for k, v in self._raw.items() if k >= n}
            self._notes = {k - n: v for k, v in self._notes.items() if k >= n}
            self._spans = {k - n: v for k, v in self._spans.items() if k >= n}
            self._late = {k - n: v for k, v in self._late.items() if k >= n}
            self._late_first = {}
            for k in sorted(self._late):
                self._late_first.setdefault(self._record[k], k)
            self._count -= n
            self.first += n
            self._details.clear()  # a dropped frame is gone everywhere

    # --- reading ------------------------------------------------------------------------------

    def __len__(self) -> int:
        """Rows held (all rows, unless a bounded index dropped some)."""
        return self._count

    @property
    def end(self) -> int:
        """One past the newest row's number."""
        with self.lock:
            return self.first + self._count

    def rows(self) -> range:
        """The numbers of the rows held."""
        with self.lock:
            return range(self.first, self.first + self._count)

    def _position(self, n: int) -> int:
        """Where row `n` sits in the columns (call with the lock held)."""
        i = n - self.first
        if not 0 <= i < self._count:
            raise IndexError(n)
        return i

    @property
    def time_base(self) -> float | None:
        """What relative times count from: the capture's first record (as tshark), else the first frame."""
        return self.t0 if self.t0 is not None else self.first_time

    @property
    def done(self) -> bool:
        return self.progress.done

    def row(self, n: int) -> Row:
        """The list row of frame `n` (its row number)."""
        with self.lock:
            i = self._position(n)
            return self._row(n, i)

    def _row(self, n: int, i: int) -> Row:
        t = self._time[i]
        msgid = self._msgid[i]
        md = self.dialect.messages.get(msgid)
        return Row(
            n, self._record[i], self._index[i], None if t != t else t, self._transports[self._transport[i]],
            self._endpoints[self._src[i]], self._endpoints[self._dst[i]], self._sysid[i], self._compid[i],
            self._seq[i], msgid, md.name if md is not None else None, self._iflags[i], CRC_CODES[self._crc[i]],
            self._securities[self._security[i]],
        )

    def raw(self, n: int) -> bytes:
        """The bytes of frame `n`."""
        with self.lock:
            return self._raw_at(self._position(n))

    def _raw_at(self, i: int) -> bytes:
        raw = self._raw.get(i)
        if raw is not None:
            return raw
        data = self._bytes  # IndexError, as for a dropped row, if the file shrank and the bytes are gone
        return b"" if data is None else data.get(self._offset[i], self._rawlen[i], exact=True)

    def frame(self, n: int) -> Frame:
        """Frame `n` as the pipeline yielded it, rebuilt from its row and bytes."""
        with self.lock:
            return self._frame(self._position(n))

    def _frame(self, i: int) -> Frame:
        raw = self._raw_at(i)
        status = CRC_CODES[self._crc[i]]
        crc = None
        if status is not CrcStatus.TRUNCATED:
            hl = HEADER_V2 if raw[0] == STX_V2 else HEADER_V1
            end = hl + raw[1]
            crc = raw[end] | (raw[end + 1] << 8)
        off = self._offset[i]
        t = self._time[i]
        f = build_frame(
            raw, 0, len(raw), status, crc, self.dialect.messages, self._record[i], self._index[i],
            None if t != t else t, self._transports[self._transport[i]], self._endpoints[self._src[i]],
            self._endpoints[self._dst[i]], None if off == NO_OFFSET else off, (), self._spans.get(i),
        )
        return f._replace(notes=self._notes.get(i, ()), security=self._securities[self._security[i]])

    def frames(self, rows: Iterable[int] | None = None) -> Iterator[Frame]:
        """Frames of `rows` (default: every row held), rebuilt one by one (not cached); rows a bounded
        index dropped meanwhile are skipped."""
        frame = self.frame
        for n in self.rows() if rows is None else rows:
            try:
                yield frame(n)
            except IndexError:
                continue

    def detail(self, n: int) -> Detail:
        """Frame `n` decoded: fields, detail tree and summary (LRU-cached)."""
        d = self._details.get(n)
        if d is None:
            frame = self.frame(n)
            fields = decode_payload(frame)
            d = Detail(frame, fields, frame_items(frame, self.dialect, fields),
                       summary_info(frame, self.dialect, fields))
            self._details.put(n, d)
        return d  # type: ignore[return-value]

    def summary(self, n: int) -> str:
        return self.detail(n).summary

    def problems(self) -> tuple[int, str | None]:
        """The damage to the capture met so far, as `read` reports it on stderr: how many problems (the
        anomalies' notes, the frames' notes of capture damage) and the first in capture order, as `read`
        writes it ("record 4: offset 301: ..."); (0, None) for none."""
        count, first = 0, None  # first: (record, where, note), "where" made for it alone (no list: O(1) memory)
        with self.lock:
            for a in self.anomalies:
                count += len(a.notes)
                if a.notes and (first is None or a.record < first[0]):
                    first = (a.record, f"record {a.record}", a.notes[0])
            for i, notes in self._notes.items():
                for n in notes:
                    if is_capture_damage(n):
                        count += 1
                        if first is None or self._record[i] < first[0]:
                            first = (self._record[i], f"frame {frame_number(self._record[i], self._index[i])}", n)
        return count, None if first is None else problem_line(first[1], first[2])

    def find_record(self, record: int) -> int | None:
        """The first row of capture record `record`. Rows are in the order frames were completed: in record
        order, but for the late rows of a TCP stream after a hole (see `_late`). A binary search over the
        running maximum of the records finds the record's first row in order; its first late row, if any,
        comes after that one (a late row's record is below one before it), so it counts only without one."""
        with self.lock:
            col, late, count = self._record, self._late, self._count
            if late:
                lo = bisect_left(range(count), record, key=lambda i: late.get(i, col[i]))
            else:
                lo = bisect_left(col, record, 0, count)
            if lo < count and col[lo] == record and lo not in late:
                return lo + self.first
            at = self._late_first.get(record)
            return None if at is None else at + self.first

    def column(self, name: str, rows: Iterable[int]) -> list[int | float | None]:
        """One column's values for `rows`, without rebuilding frames (to pick rows out of a whole
        capture); None for rows no longer held. Names: record, time, sysid, compid, seq, msgid, crc."""
        cols: dict[str, array[int] | array[float]] = {
            "record": self._record, "time": self._time, "sysid": self._sysid, "compid": self._compid,
            "seq": self._seq, "msgid": self._msgid, "crc": self._crc}
        col = cols[name]
        with self.lock:
            first, count = self.first, self._count
            return [col[n - first] if 0 <= n - first < count else None for n in rows]

    def memory(self) -> int:
        """Bytes held by the columns and side tables (an estimate, for the docs and tests)."""
        cols = (self._record, self._index, self._time, self._transport, self._src, self._dst, self._offset,
                self._rawlen, self._crc, self._iflags, self._sysid, self._compid, self._seq, self._msgid,
                self._security)
        total = sum(c.buffer_info()[1] * c.itemsize for c in cols)
        total += sum(len(b) + 33 for b in self._raw.values()) + 100 * len(self._raw)
        total += 150 * (len(self._notes) + len(self._spans)) + 100 * (len(self._late) + len(self._late_first))
        return total

    def close(self) -> None:
        data, self._bytes = self._bytes, None
        if data is not None:
            data.close()
