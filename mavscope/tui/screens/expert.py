"""`e`: expert findings (mavscope.analysis.expert) and those of the shipped pack of detection rules
(mavscope.rules, as `audit` runs it), most severe first; Enter jumps to the first frame."""

from __future__ import annotations

from collections.abc import Iterator

from rich.text import Text
from textual.app import ComposeResult
from textual.widgets import DataTable, Label

from mavscope.analysis.expert import Expert
from mavscope.analysis.selection import Selection
from mavscope.mavlink.frame import Frame
from mavscope.notes import Finding, Severity, sort_findings
from mavscope.output.console import text
from mavscope.rules import RuleEngine, pack_rules
from mavscope.tui.screens.analysis import AnalysisScreen, first_rows
from mavscope.tui.verdicts import BLUE, DIM, ORANGE, RED
from mavscope.tui.widgets.words import Table, Title

SEVERITY_STYLE = {Severity.ERROR: RED, Severity.WARN: ORANGE, Severity.NOTE: BLUE, Severity.CHAT: DIM}


class ExpertScreen(AnalysisScreen):
    TITLE_TEXT = "Expert findings"
    DEFAULT_CSS = """
    ExpertScreen DataTable { height: 1fr; }
    ExpertScreen Label { padding: 0 1; }
    """

    def compose_body(self) -> ComposeResult:
        yield Title("Enter: go to the finding's first frame", id="expert-title")
        yield Table(id="findings", cursor_type="row", zebra_stripes=True)

    def analyse(self, frames: Iterator[Frame], selection: Selection) -> list[Finding]:
        dialect = self.index.dialect
        expert, rules = Expert(dialect), RuleEngine(pack_rules(dialect))  # the shipped pack, as audit runs it
        for f in frames:
            rules.add(f, expert.add(f))  # the fields the expert decoded, decoded once
        found = sort_findings(expert.findings() + rules.findings())
        return [f for f in found if selection.any_record(f.frames)]

    def show(self, result: object) -> None:
        findings: list[Finding] = result  # type: ignore[assignment]
        table = self.query_one("#findings", DataTable)
        table.add_columns("Severity", "Code", "Finding", "Frames")
        listed, cut = first_rows(findings, "stats")
        for i, f in enumerate(listed):
            frames = ", ".join(map(str, f.frames[:8])) + ("…" if len(f.frames) > 8 else "")
            code = f"{f.code} {f.rule}" if f.rule else f.code  # a detection rule's finding: "rule ID"
            table.add_row(Text(f.severity.value, style=SEVERITY_STYLE.get(f.severity, "")), code,
                          text(f.message), frames, key=str(i))  # a message is no markup
        counts = {s: sum(1 for f in findings if f.severity is s) for s in Severity}
        summary = ", ".join(f"{n} {s.value}" for s, n in counts.items() if n) or "no findings"
        self.query_one("#expert-title", Label).update(f"{summary}{cut}.  Enter: go to the finding's first frame")
        table.focus()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        findings: list[Finding] = self.result  # type: ignore[assignment]
        if event.row_key.value is None:
            return
        f = findings[int(event.row_key.value)]
        if f.frames:
            self.dismiss(None)
            self.app.goto_record(f.frames[0])  # type: ignore[attr-defined]
