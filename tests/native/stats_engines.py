"""Both engines of `mavscope stats`, through the API, as comparable values.

`pure_stats` is the per-frame reference (Dissector, SecurityStage, then StatsBuilder.add and Expert.add
frame by frame, problems through `Problems`); `native_stats_of` is what `stats` runs on the native engine:
the native walker's windows as FrameBatches (mavscope.native.windows.batches, notes as codes) into
StatsBuilder.add_batch and expert_batch.feed. `observed`
turns either into what the command's outputs are made of: the `--json` document (rows, totals,
findings), the order of the streams (the busiest ones are picked by a stable sort: ties keep it) and of
the conversations, every stream's sparkline series, and what went to stderr.
"""

from __future__ import annotations

import io
from pathlib import Path

from mavscope.analysis.expert import Expert
from mavscope.analysis.stats import Stats, compute_stats
from mavscope.capture.detect import open_capture
from mavscope.cli import Env
from mavscope.commands.common import Problems
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.security.stage import SecurityStage
from tests.native.engines import material


def observed(stats: Stats, findings: list[Finding], err: str) -> dict[str, object]:
    return {
        "json": stats.to_json(),
        "findings": [f.to_json() for f in findings],
        "stream_order": list(stats.streams),
        "conversation_order": list(stats.conversations),
        "series": {key: stats.rate_series(key, 40) for key in stats.streams},
        "stderr": err,
    }


def pure_stats(path: str | Path, dialect: Dialect, keys: str = "none") -> dict[str, object]:
    err = io.StringIO()
    problems = Problems(Env(stdout=io.StringIO(), stderr=err, environ={}), str(path))
    expert = Expert(dialect)
    stage = SecurityStage(material(keys))
    frames: list[Frame] = []
    with open_capture(path) as reader:
        for item in stage.run(Dissector(dialect).run(reader)):
            if type(item) is Anomaly:
                problems.anomaly(item)
                continue
            if item.notes:
                problems.frame(item)
            frames.append(item)
    problems.close()
    stats = compute_stats(frames, expert)
    stats.logged_in_part = frozenset()  # (the command sets it from the expert)
    return observed(stats, expert.findings(), err.getvalue())


def native_stats_of(path: str | Path, dialect: Dialect, keys: str = "none",
                    limit: int | None = None) -> dict[str, object]:
    """The native engine's observed outputs (`limit`: rows per window, to cut batches small)."""
    from mavscope.analysis import expert_batch
    from mavscope.analysis.stats import StatsBuilder
    from mavscope.capture.detect import detect_kind
    from mavscope.native import windows
    from mavscope.pipeline.batch import Tables

    err = io.StringIO()
    problems = Problems(Env(stdout=io.StringIO(), stderr=err, environ={}), str(path))
    builder, expert = StatsBuilder(), Expert(dialect)
    for b in windows.batches(str(path), detect_kind(path), dialect, SecurityStage(material(keys)), problems.item,
                             Tables(), limit or windows.WINDOW_FRAMES):
        expert_batch.feed(expert, b, builder.add_batch(b))
    problems.close()
    stats = builder.result()
    stats.logged_in_part = frozenset()
    return observed(stats, expert.findings(), err.getvalue())
