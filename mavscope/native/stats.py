"""`mavscope stats` on the native engine: one accumulator fed by the C walker and the Python pipeline.

The walker (src/mavscope_native/walk.c with `stats=`) takes the clean records as the JSON Lines walk
does and puts their frames into the C accumulator (acc.h: StatsBuilder and the expert detectors that see
every frame, ported step for step); every record it hands back goes through the Python pipeline
(Dissector.feed, the security stage) and its frames into the same accumulator (`_native.Stats.add`), in
capture order, and into the detectors that only such frames can feed (BadCrcBursts, KeyLeaks, HiddenFrames). At
the end the accumulator's state (`dump()`, layout in acc_dump.c) becomes the very Python objects the
pure path builds (Stats with its _Stream, _Link, _Conversation, RateHistogram, SeqTracker; the Expert's
detectors), whose own code then writes the rows, the JSON and the findings' sentences.

When a table of the accumulator reaches a cap the Python classes do not have (acc.h MS_CAP_*), the
native pass gives up (`None`) and the command runs the pure path, which is the reference.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable

from mavscope.analysis.stats import Stats
from mavscope.capture.reader import WINDOW
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.native.core import _native
from mavscope.native.dump import Accumulator, plan_for
from mavscope.native.tables import table_for
from mavscope.native.walk import NativeWalk, Reporter
from mavscope.notes import Finding
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.security.stage import SecurityStage


class NativeStats:
    """What a native pass made: the statistics, the expert findings, and how many frames it saw."""

    def __init__(self, stats: Stats, findings: list[Finding], frames: int, size: int,
                 logged_in_part: frozenset[tuple[int, int]] = frozenset()) -> None:
        self.stats = stats
        self.findings = findings
        self.frames = frames
        self.size = size
        self.logged_in_part = logged_in_part  # Expert.logged_in_part


def native_stats(path: str | os.PathLike[str], dialect: Dialect, stage: SecurityStage, problems: Reporter,
                 kind: str | None = None, window: int = WINDOW) -> NativeStats | None:
    """Statistics and findings of a whole capture, as `stats` computes them on the pure path (every frame,
    no filter); anomalies and frames with notes go to `problems` as there. None when the dialect has no
    plan or a table of the accumulator filled up: run the pure path instead (nothing was printed)."""
    plan = plan_for(dialect)
    if _native is None or plan is None:
        return None
    acc = Accumulator(_native.Stats(table_for(dialect), plan))
    dissector = Dissector(dialect, stage.material.wifi)
    run = stage.run
    nokey: Callable[[], bool] = lambda: not stage.check_signatures  # noqa: E731 - asked per batch

    def python(items: Iterable[Frame | Anomaly]) -> None:
        for item in run(items):
            if type(item) is Anomaly:
                problems.anomaly(item)
                continue
            if item.notes:
                problems.frame(item)
            acc.add(item)

    with NativeWalk(path, dialect, dissector.mavlink_endpoints, stage.signed_senders, kind, window,
                    stats=acc.acc, receivers=dissector.receivers) as walk:
        for walked, _text, record in walk.batches(nokey):
            if acc.full():
                break
            if walked is not None:
                held = dissector.passed(*walked)  # a run of tlog text entries ends before these records
                if held:
                    python(held)
            if record is not None:
                python(dissector.feed(record))
        counters = walk.stats()
    del walk  # the walker holds the accumulator: gone, the accumulator's C state goes once dumped
    if not acc.full():
        python(dissector.finish())
    if acc.full():
        return None
    stats, ex = acc.result(dialect)
    return NativeStats(stats, ex.findings(), acc.frames + counters["frames_native"], counters["size"],
                       ex.logged_in_part())
