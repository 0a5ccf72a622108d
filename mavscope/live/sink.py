"""`live -w OUT.pcap [--ring N]`: a pcap written as records arrive, flushed at least every second.

Flushing hands the bytes to the operating system, so a crash or kill of mavscope loses at most the
last second (a power cut can lose what the OS had not yet written to disk: no fsync per second).

Ring mode keeps at most N MB on disk in two files that alternate: records go to OUT until it would
pass N/2 MB, then OUT becomes OUT.1 (replacing the previous OUT.1) and a new OUT starts. Every file is a
complete pcap; OUT.1 then OUT hold the newest N/2 to N MB in order (`mergecap OUT.1 OUT`). A single
record larger than N/2 MB (at most 64 KiB for UDP) still gets written. `-w OUT --ring N` replaces both
OUT and OUT.1 of an earlier run.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from typing import BinaryIO

from mavscope.capture.base import Record
from mavscope.capture.writer import DEFAULT_SNAPLEN, PcapWriter
from mavscope.errors import UsageError

MB = 1_000_000
FLUSH_INTERVAL = 1.0
_FILE_HEADER = 24
_RECORD_HEADER = 16


class LivePcapWriter:
    """Appends Records to a classic pcap of one link type, flushing every `flush_interval` seconds."""

    def __init__(self, path: str, linktype: int, ring_mb: float | None = None,
                 flush_interval: float = FLUSH_INTERVAL, file: BinaryIO | None = None) -> None:
        """`file`: where to write instead of `path` (standard output for `-w -`: no ring, left open)."""
        if ring_mb is not None and ring_mb < 0.1:
            raise UsageError("live: --ring needs at least 0.1 MB")
        if ring_mb is not None and file is not None:
            raise UsageError("live: --ring keeps files on disk: it cannot go with -w -")
        self.path = path
        self.linktype = linktype
        self.half = int(ring_mb * MB) // 2 if ring_mb is not None else None
        self.flush_interval = flush_interval
        self.records = 0  # written, all files
        self.rotations = 0
        self._writer = PcapWriter(path if file is None else file, linktype)
        if self.half is not None and os.path.exists(path + ".1"):
            os.remove(path + ".1")  # a previous run's older half: OUT and OUT.1 belong to this run now
        self._size = _FILE_HEADER
        self._count = 0  # records in the current file
        self._dirty = False
        self._last_flush = time.monotonic()

    def write(self, rec: Record) -> None:
        size = _RECORD_HEADER + min(len(rec.data), DEFAULT_SNAPLEN)
        if self.half is not None and self._count and self._size + size > self.half:
            self._rotate()
        self._writer.write(rec.time, rec.data, rec.orig_len)
        self._size += size
        self._count += 1
        self.records += 1
        self._dirty = True
        if time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()

    def write_batch(self, records: bytes, count: int, each: Callable[[], Iterable[Record]]) -> None:
        """Append `count` records already in the file's format (microsecond pcap records: a live batch
        converted in C) in one write; where a ring rotation falls inside them, record by record (`each()`
        gives them as Records), so the files split exactly as `write` splits them."""
        if self.half is not None and self._size + len(records) > self.half:
            for rec in each():
                self.write(rec)
            return
        self._writer.write_raw(records)
        self._size += len(records)
        self._count += count
        self.records += count
        self._dirty = True
        if time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()

    def tick(self) -> None:
        """Flush when due (call this while no records arrive, too)."""
        if self._dirty and time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        self._writer.flush()
        self._dirty = False
        self._last_flush = time.monotonic()

    def _rotate(self) -> None:
        self._writer.close()
        os.replace(self.path, self.path + ".1")
        self._writer = PcapWriter(self.path, self.linktype)
        self._size = _FILE_HEADER
        self._count = 0
        self.rotations += 1

    def files(self) -> list[str]:
        """The files holding the capture, oldest first."""
        older = self.path + ".1"
        return ([older] if self.rotations else []) + [self.path]

    def close(self) -> None:
        self._writer.close()
