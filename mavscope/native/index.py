"""The native build of a FrameIndex: the C walker's column mode fills the index columns in bulk.

The C walker (src/mavscope_native, column mode: columns.h) takes the records whose frames are all clean
(docs/native.md: CRC ok, no note, no unknown or encryption flag, no key message, signed frames only
while no signing key is configured), and hands every other record back, in capture order. Here its
chunks become index rows with a few numpy operations per chunk (`FrameIndex.extend`), and the records it
hands back go through the pure path's `Dissector.feed` and security stage into `FrameIndex.add`, exactly
as the export's native batch source (mavscope/native/export.py) merges the two. What a native row holds
is what `add` would have stored for the same frame: the frame is clean, so its CRC code is ok, it has no
note, no span and no security verdict (the stage leaves a clean frame alone: an unsigned plaintext
frame, or a signed one while no key is configured), and its bytes lie at its offset in the file.

The walker runs in "index" mode (`Columns(..., index=True)`): it fills only the fixed-width columns the
index takes, not the payloads, wire bytes and message rows the export reads.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from mavscope.browse.rows import Progress
from mavscope.capture.detect import open_capture
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.native.core import COLUMN_TRANSPORTS, KINDS, _native
from mavscope.native.tables import table_for
from mavscope.native.windows import DONE, FINISH, NATIVE, column_steps, column_walker
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.security.stage import SecurityStage

FIRST_CHUNK = 256  # frames in the first chunk: the first rows go out at once
CHUNK = 1 << 18  # frames per chunk afterwards
_TRANSPORTS = tuple(t or "" for t in COLUMN_TRANSPORTS)  # the transport column's codes -> names ("": none)


def indexes(kind: str) -> bool:
    """Whether the native index reads a capture of `kind` (every kind the walker reads, raw streams too);
    whether the native engine runs at all is the session's choice (`Session.engine`)."""
    return kind in KINDS


class Chunk:
    """The index's columns of one chunk the walker took, as numpy arrays (views of its buffers)."""

    def __init__(self, n: int, blocks: list[Any], names: tuple[str, ...]) -> None:
        b = dict(zip(names, blocks))
        self.n = n

        def view(name: str, dtype: str) -> np.ndarray:
            return np.frombuffer(b[name], np.dtype(dtype).newbyteorder("="), count=n)

        self.record = view("record", "i8")
        self.index = view("index", "i4")
        self.time = view("time", "f8")
        self.time_ok = view("time_ok", "u1")
        self.transport = view("transport", "u1")
        self.src = view("src", "i4")
        self.dst = view("dst", "i4")
        self.iflags = view("incompat_flags", "u1")
        self.seq = view("seq", "u1")
        self.sysid = view("sysid", "u1")
        self.compid = view("compid", "u1")
        self.msgid = view("msgid", "u4")
        self.offset = view("offset", "i8")
        self.size = view("size", "u2")


def native_build(index: Any, path: str, dialect: Dialect, stage: SecurityStage, *,
                 on_progress: Callable[[Progress], object] | None = None,
                 cancelled: Callable[[], bool] = lambda: False, every: int = 8192) -> Progress:
    """Fill `index` (a FrameIndex of `path`) with every frame of the capture: native chunks in bulk, the
    handed-back records through `Dissector` and `stage` (the pipeline without a display filter). Returns
    the final progress, as FrameIndex.build does (cancelled: stops after the chunk at hand)."""
    assert _native is not None
    with open_capture(path) as reader:  # the capture's errors first, as the pure build gives them
        kind = reader.kind
    dissector = Dissector(dialect, stage.material.wifi)
    cols = _native.Columns(table_for(dialect), FIRST_CHUNK, index=True)
    ends: list[int] = []  # walker endpoint id -> index endpoint id
    ends_map = np.zeros(1, np.uint32)  # ends, offset by one: position 0 is the walker's -1 (no endpoint)
    same = [True]  # ends_map[k] == k: the walker's endpoint ids + 1 are the index's
    names = _native.COLUMN_NAMES
    told_at = [0]  # items indexed when progress was last told
    items = [0]

    def python(got: Iterable[Frame | Anomaly]) -> None:
        add = index.add
        for item in stage.run(got):
            if type(item) is Anomaly:
                index.anomalies.append(item)
            else:
                add(item)
            items[0] += 1

    def chunk() -> None:
        nonlocal ends_map
        n, reset, new_ends, blocks, _parts = cols.take()
        if reset:
            ends.clear()
        if new_ends:
            ends.extend(index.endpoint_id(Endpoint.from_packed(a, port)) for a, port in new_ends)
        if reset or new_ends:
            ends_map = np.array([0] + ends, np.uint32)
            same[0] = bool((ends_map == np.arange(len(ends_map))).all())
        if n:
            index.extend(Chunk(n, blocks, names), None if same[0] else ends_map, _TRANSPORTS)
            items[0] += n

    with column_walker(path, kind, dialect, stage, dissector, cols) as (walker, size):
        first = True
        for kind_, got, _at in column_steps(walker, cols, dissector, lambda: not stage.check_signatures):
            if kind_ == NATIVE:
                chunk()  # the batch's native rows, before the records it handed back
                continue
            python(got)
            if kind_ == FINISH:
                chunk()
                break
            if kind_ != DONE:
                continue
            if first and items[0]:
                first = False
                cols.limit = CHUNK
            if items[0] - told_at[0] >= every or told_at[0] == 0 and items[0]:
                told_at[0] = items[0]
                position = int(walker.stats()["position"])
                index.progress = Progress(len(index), position, size, False)
                if on_progress is not None:
                    on_progress(index.progress)
                if cancelled():
                    index.progress = Progress(len(index), position, size, False, True)
                    if on_progress is not None:
                        on_progress(index.progress)
                    return index.progress
    index.progress = Progress(len(index), size, size, True)
    if on_progress is not None:
        on_progress(index.progress)
    return index.progress
