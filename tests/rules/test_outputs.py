"""Rule findings in the outputs besides `audit` (tests/rules/test_files.py has its text and JSON): the export's
findings table, from both batch sources, and the TUI's findings screen (its analysis, run without the app).
The capture is built to trigger one rule (tests/support/ruleflows.py): an armed vehicle's HEARTBEAT, then
MAV_CMD_DO_FLIGHTTERMINATION with param1 1, record 2."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from mavscope.analysis.selection import Selection
from mavscope.export.options import ExportOptions
from mavscope.export.schema import FINDINGS, table_of
from mavscope.export.source import record_batches
from mavscope.mavlink.dialect import load_dialect
from mavscope.native.core import available
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from mavscope.tui.screens.expert import ExpertScreen
from tests.support.ruleflows import write_case

RULE = "cmd-flight-termination"
SOURCES = ["python", "native"] if available() else ["python"]


@pytest.mark.parametrize("source", SOURCES)
def test_the_export_findings_table_has_the_rule_column(source: str, tmp_path: Path) -> None:
    cap = write_case(tmp_path, RULE, True)
    rows = [r for b in record_batches(cap, ExportOptions(source=source, tables=frozenset({FINDINGS})))
            if table_of(b) == FINDINGS for r in b.to_pylist()]
    ruled = [(r["source"], r["code"], r["severity"], r["rule"], r["frames"]) for r in rows if r["rule"] is not None]
    assert ruled == [("audit", "rule", "error", RULE, [2])]
    assert all(r["rule"] is None for r in rows if r["code"] != "rule")


def test_the_tui_findings_screen_lists_rule_findings(tmp_path: Path) -> None:
    dialect = load_dialect([])
    cap = write_case(tmp_path, RULE, True)
    with open_session(str(cap), PipelineOptions(), dialect=dialect) as session:
        frames = [f for f in session.items if type(f) is not Anomaly]
    screen = SimpleNamespace(index=SimpleNamespace(dialect=dialect))
    found = ExpertScreen.analyse(screen, iter(frames), Selection())  # type: ignore[arg-type]
    assert [(f.rule, f.frames) for f in found if f.code == "rule"] == [(RULE, (2,))]
