"""What the app's thread workers do, as plain functions: fill an index from a frame source, and scan an
index with a display filter. They talk to the app only through `post` (messages) and `cancelled`."""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable

from textual.message import Message

from mavscope.browse.fastfilter import Cancelled as FilterCancelled
from mavscope.browse.fastfilter import ColumnFilter
from mavscope.browse.index import PROGRESS_EVERY, FrameIndex
from mavscope.browse.rows import Progress
from mavscope.filter import DisplayFilter
from mavscope.tui.messages import FilterProgress, IndexProgress
from mavscope.tui.sessions import FrameSource, LiveFrameSource, LiveReader

Post = Callable[[Message], object]
Cancelled = Callable[[], bool]


def fill_index(index: FrameIndex, source: FrameSource, post: Post, cancelled: Cancelled) -> None:
    """Walk `source`'s pipeline into `index`, posting IndexProgress as it goes (natively where the
    engine reads the capture: mavscope.native.index)."""
    if source.index_natively(index, lambda p: post(IndexProgress(index, p)), cancelled):
        return
    reader, items, index.t0 = source.open()
    with reader:  # type: ignore[attr-defined]  # a CaptureReader or a LiveReader
        if isinstance(reader, LiveReader) and isinstance(source, LiveFrameSource):
            last = [0.0]

            def idle() -> None:  # no traffic: take new keys, show what came, stop when the app goes
                if cancelled():
                    source.stop()
                source.take_keys()
                now = time.monotonic()
                if now - last[0] > 0.2:
                    last[0] = now
                    post(IndexProgress(index, Progress(len(index), 0, 0, False)))

            reader.on_idle = idle
        index.build(items, position=lambda: reader.position, total=reader.size,  # type: ignore[attr-defined]
                    on_progress=lambda p: post(IndexProgress(index, p)),
                    cancelled=cancelled, every=256 if source.live else PROGRESS_EVERY)


def scan_filter(flt: DisplayFilter, index: FrameIndex, rows: array, post: Post, cancelled: Cancelled) -> None:
    """Fill `rows` with the rows `flt` matches (following a live index as it grows), posting FilterProgress.
    The filter runs over the index's columns (mavscope.browse.fastfilter: vectorised where it can be, the
    exact predicate on the frames of the rest)."""
    fast = ColumnFilter(flt, index, cancelled)
    start = done = index.first  # row numbers: a bounded live index drops rows but never renumbers
    last_post = time.perf_counter()
    try:
        while True:
            complete = index.done or index.progress.cancelled
            end = index.end
            for stop, hits in fast.scan(max(done, index.first), end):
                rows.frombytes(hits.tobytes())
                now = time.perf_counter()
                if now - last_post > 0.1:
                    last_post = now
                    post(FilterProgress(flt, rows, stop - start, max(end - start, 1), False))
            done = end
            if complete and done == index.end:
                break
            post(FilterProgress(flt, rows, done - start, max(end - start, 1), False))
            time.sleep(0.05)
            if cancelled():
                return
    except FilterCancelled:
        return
    post(FilterProgress(flt, rows, done - start, done - start, True))
