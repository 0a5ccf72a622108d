"""The native walker's column mode: a capture as windows of frames in capture order.

`windows(path, kind, dialect, stage)` walks the capture with the C extension (src/mavscope_native,
column mode: columns.h): the records whose frames are all clean, or carry only the notes the chunk gives
as codes (an unsigned frame of a sender that signs, a bad CRC: `noted`), fill column buffers in bulk (a
`Chunk` of numpy views), every other record is handed back, in capture order, to `Dissector.feed` and the
security stage, and its frames and anomalies join the window after as many native rows as came before
them. A `Window` holds at most `limit` rows; `FrameBatch.of_window` makes one batch of it. The export
(its tables) and `stats` (its analyses) read the same windows.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from mavscope.capture.reader import WINDOW, handed_back_record, open_file
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect, MessageDef
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.framing import with_bad_crc
from mavscope.native.chunk import Chunk
from mavscope.native.core import KINDS, NOTE_BAD_CRC, _native
from mavscope.native.core import available as available  # the engine choice, for the session
from mavscope.native.tables import table_for
from mavscope.pipeline.batch import FrameBatch, Tables
from mavscope.pipeline.dissect import MAVLINK_PORTS, Anomaly, Dissector
from mavscope.security.stage import SecurityStage, with_unsigned_note

WINDOW_FRAMES = 65_536  # rows per window


@dataclass
class Window:
    """A window's rows: chunk `chunk`'s and the handed-back frames `py`, the j-th after `pos[j]` native
    rows; its anomalies, each after so many of `py`; the walker's endpoints (`ends`: its ids index them;
    `reset`: the list began anew here) and, per message, its payload rows (`_native.Columns.take`)."""

    chunk: Chunk
    py: list[Frame] = field(default_factory=list)
    pos: list[int] = field(default_factory=list)
    anomalies: list[tuple[int, Anomaly]] = field(default_factory=list)
    ends: list[Endpoint] = field(default_factory=list)
    reset: bool = False
    parts: list[tuple[int, Any, Any, int]] = field(default_factory=list)


def noted(frame: Frame, code: int) -> Frame:
    """The Frame of a row whose notes the chunk gives as a code (columns.h MS_NOTE_*), as the Python pipeline
    makes it: the framer's bad-CRC note first, then the security stage's unsigned-in-signed-stream (or
    v1-in-signed-stream) note."""
    if code & NOTE_BAD_CRC:
        frame = with_bad_crc(frame)
    if code & ~NOTE_BAD_CRC:
        frame = with_unsigned_note(frame)
    return frame


def messages_of(dialect: Dialect) -> list[MessageDef]:
    """The dialect's messages in the layout table's order (table_blob.build_table's)."""
    return sorted(dialect.messages.values(), key=lambda m: m.id)


class _Walk:
    def __init__(self, stage: SecurityStage, dissector: Dissector) -> None:
        self.stage, self.dissector = stage, dissector
        self.py: list[Frame] = []
        self.pos: list[int] = []
        self.anomalies: list[tuple[int, Anomaly]] = []
        self.ends: list[Endpoint] = []

    def python(self, items: Iterable[Frame | Anomaly], at: int) -> None:
        """Items of the Python pipeline, after `at` native frames of the window."""
        for item in self.stage.run(items):
            if type(item) is Anomaly:
                self.anomalies.append((len(self.py), item))
            else:
                self.pos.append(at)
                self.py.append(item)

    def take(self, taken: tuple[int, bool, list[tuple[bytes, int]], list[Any], list[tuple[int, Any, Any, int]]],
             ) -> Window:
        assert _native is not None
        n, reset, new_ends, columns, parts = taken
        if reset:
            self.ends = []
        self.ends = self.ends + [Endpoint.from_packed(a, port) for a, port in new_ends]
        w = Window(Chunk(n, columns, _native.COLUMN_NAMES), self.py, self.pos, self.anomalies, self.ends, reset,
                   parts)
        self.py, self.pos, self.anomalies = [], [], []
        return w


# what `column_steps` yields: items of the Python pipeline (records handed back, what the dissector held),
# the walker's return after a batch of native rows, and the end of the capture's items
HELD, NATIVE, BACK, DONE, FINISH = "held", "native", "back", "done", "finish"
Step = tuple[str, Iterable[Frame | Anomaly], int]


def column_steps(walker: _native.Walker, cols: _native.Columns, dissector: Dissector,
                 signed_nokey: Callable[[], bool]) -> Iterator[Step]:
    """The one walk of the column mode, in capture order (the export, the TUI's index and `windows` read it):
    per batch of the walker, what the dissector held from before the batch's records (HELD, placed before the
    batch's native rows: `at` counts the native rows before them), then NATIVE (the batch's rows are in
    `cols`), then each record it handed back through the dissector (BACK), then DONE (the batch is over:
    where a consumer takes a chunk and sets `cols.limit` for the next); at the end what the dissector's
    finish gives (FINISH)."""
    step, walked, told = walker.next, walker.walked, None
    none: tuple[Frame | Anomaly, ...] = ()
    while True:
        before = cols.frames
        segs = step(signed_nokey(), 1 << 20, None)
        if segs is None:
            last = walked()
            if last is not None and last != told:
                yield HELD, dissector.passed(*last), cols.frames
            break
        told = walked()
        if told is not None:
            held = dissector.passed(*told)
            if held:
                yield HELD, held, before
        yield NATIVE, none, cols.frames
        for seg in segs:
            if type(seg) is tuple:
                yield BACK, dissector.feed(handed_back_record(seg)), cols.frames
        yield DONE, none, cols.frames
    yield FINISH, dissector.finish(), cols.frames


@contextmanager
def column_walker(path: str, kind: str, dialect: Dialect, stage: SecurityStage, dissector: Dissector,
                  cols: _native.Columns) -> Iterator[tuple[_native.Walker, int]]:
    """The one column-mode walker (the analyses' windows, the export, the TUI's index): the capture opened,
    a Walker filling `cols` with the dissector's and the security stage's shared sets, MAVLink's ports and a
    raw stream's link (as the JSON Lines walk has them: a raw stream's clean stretches become rows, numbered
    on from `dissector.raw.frames`, and only the pieces around damage are handed back), and the file's size;
    closed at the end."""
    assert _native is not None
    _, f, size = open_file(path)
    try:
        walker = _native.Walker(f.fileno(), size, KINDS[kind], table_for(dialect), dissector.mavlink_endpoints,
                                Endpoint.from_packed, stage.signed_senders, WINDOW, columns=cols,
                                receivers=dissector.receivers, ports=tuple(sorted(MAVLINK_PORTS)),
                                raw=dissector.raw)
        try:
            yield walker, size
        finally:
            walker.close()
    finally:
        f.close()


def windows(path: str, kind: str, dialect: Dialect, stage: SecurityStage, limit: int = WINDOW_FRAMES,
            progress: Any = None, stats: dict[str, int] | None = None) -> Iterator[Window]:
    """The capture's frames in windows of at most `limit` rows (see the module docstring); `progress(position)`
    after each window; `stats` gets the walker's counts."""
    assert _native is not None
    dissector = Dissector(dialect, stage.material.wifi)
    walk = _Walk(stage, dissector)
    cols = _native.Columns(table_for(dialect), limit, notes=True)
    with column_walker(path, kind, dialect, stage, dissector, cols) as (walker, _size):
        for kind_, items, at in column_steps(walker, cols, dissector, lambda: not stage.check_signatures):
            walk.python(items, at)
            if kind_ == FINISH:
                yield walk.take(cols.take())
            elif kind_ == DONE:
                if cols.frames + len(walk.py) >= limit:
                    yield walk.take(cols.take())
                    if progress is not None:
                        progress(int(walker.stats()["position"]))
                cols.limit = max(1, limit - len(walk.py))
        if stats is not None:
            stats.update(walker.stats())

def batches(path: str, kind: str, dialect: Dialect, stage: SecurityStage, report: Callable[[Frame | Anomaly], object],
            tables: Tables, limit: int = WINDOW_FRAMES, stats: dict[str, int] | None = None) -> Iterator[FrameBatch]:
    """The capture's frames as a FrameBatch per window (`Session.batches` on the native engine), ids from
    `tables`; `report` gets each anomaly and each handed-back frame with notes, in capture order (the rows
    the chunk notes by code carry none that tells of capture damage: a bad CRC, an unsigned frame)."""
    messages = messages_of(dialect)
    for w in windows(path, kind, dialect, stage, limit, stats=stats):
        after = iter(w.anomalies)
        j, anomaly = next(after, (-1, None))
        for k, f in enumerate(w.py):
            while anomaly is not None and j <= k:
                report(anomaly)
                j, anomaly = next(after, (-1, None))
            if f.notes:
                report(f)
        while anomaly is not None:
            report(anomaly)
            j, anomaly = next(after, (-1, None))
        yield FrameBatch.of_window(w.chunk, w.py, w.pos, w.ends, messages, tables, w.reset, noted)
