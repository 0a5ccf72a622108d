"""What the analysis commands (stats, mission, commands, timeline) share: their options, and one pass
over every frame of the capture.

Every analysis runs over every frame; `-Y` only selects which rows are reported (`Selection`), as in
Wireshark's sequence analysis: a filter must not turn a healthy link into a lossy one, or an answered
command into an unanswered one.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING

from mavscope.analysis.selection import Selection
from mavscope.cli import Env
from mavscope.commands.common import (
    Problems,
    add_capture_options,
    add_filter_option,
    add_key_options,
    capture_session,
)
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.session import Session

if TYPE_CHECKING:
    from mavscope.output.grid import Cell


def add_analysis_options(p: argparse.ArgumentParser) -> None:
    add_capture_options(p)
    add_filter_option(p)
    add_key_options(p)  # signature and encryption verdicts for filters, statistics and findings
    p.add_argument("--json", action="store_true", help="write one JSON document to stdout (docs/analysis.md)")


class Pass:
    """One pass over a session's frames: every frame (anomalies reported on stderr as `read` does), each
    seen by the selection first."""

    def __init__(self, session: Session, env: Env, anomaly: Callable[[Anomaly], None] | None = None) -> None:
        self.session = session
        self.env = env
        self.selection = Selection(session.display_filter)
        self.anomaly = anomaly  # also given each anomaly

    def __iter__(self) -> Iterator[Frame]:
        see = self.selection.see
        problems = Problems(self.env, self.session.name)
        try:
            for item in self.session.items:
                if type(item) is Anomaly:
                    problems.anomaly(item)
                    if self.anomaly is not None:
                        self.anomaly(item)
                    continue
                if item.notes:
                    problems.frame(item)
                see(item)
                yield item
        finally:
            problems.close()


def print_findings(con, findings: Sequence[Finding]) -> None:  # type: ignore[no-untyped-def]
    """The expert findings as a table on the rich console `con` (nothing when there are none)."""
    if not findings:
        return
    from mavscope.output.console import text
    from mavscope.output.grid import Column, print_table
    from mavscope.output.tables import listed

    def row(f: Finding) -> list[Cell]:  # (the first frames and how many more: --json lists them all)
        return [f.severity.value, f.code, listed(f.frames), text(f.message)]

    print_table(con, [Column("severity", key=True), Column("code", key=True), Column("frames"), Column("message")],
                findings, row, title="Expert findings")


@contextmanager
def analysis_pass(args: argparse.Namespace, env: Env) -> Iterator[Pass]:
    """The capture named by `args`, ready for one pass over every frame."""
    with capture_session(args, env) as session:
        yield Pass(session, env)

