"""`v`: the flight's story (mavscope.analysis.events, as `mavscope events`): one row per event in capture
order; Enter jumps to the event's frame in the packet list."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator

from rich.text import Text
from textual.app import ComposeResult
from textual.widgets import DataTable, Label

from mavscope.analysis.events import Event, EventLog
from mavscope.analysis.selection import Selection
from mavscope.mavlink.frame import Frame
from mavscope.output.console import text
from mavscope.tui.screens.analysis import AnalysisScreen, first_rows
from mavscope.tui.verdicts import BLUE, DIM, GREEN, ORANGE, RED
from mavscope.tui.widgets.words import Table, Title

KIND_STYLE = {"arming": ORANGE, "mode": BLUE, "failsafe": RED, "reboot": ORANGE, "link": RED, "signing": ORANGE,
              "command": GREEN, "mission": BLUE, "statustext": "", "param": DIM, "file": DIM, "vehicle": "bold"}


class EventsScreen(AnalysisScreen):
    TITLE_TEXT = "Events"
    DEFAULT_CSS = """
    EventsScreen DataTable { height: 1fr; }
    EventsScreen Label { padding: 0 1; }
    """

    counts: Counter[str] = Counter()
    dropped: Counter[str] = Counter()

    def compose_body(self) -> ComposeResult:
        yield Title("Enter: go to the event's frame", id="events-title")
        yield Table(id="events", cursor_type="row", zebra_stripes=True)

    def analyse(self, frames: Iterator[Frame], selection: Selection) -> list[Event]:
        log = EventLog(self.index.dialect)
        for f in frames:
            log.add(f)
        result = log.finish()
        self.counts, self.dropped = result.counts, result.dropped
        return [e for e in result.events if selection.any_record((e.frame,))]

    def show(self, result: object) -> None:
        events: list[Event] = result  # type: ignore[assignment]
        table = self.query_one("#events", DataTable)
        table.add_columns("Frame", "Time", "Kind", "From", "Event")
        base = self.index.time_base
        listed, cut = first_rows(events, "events")
        for i, e in enumerate(listed):
            when = f"{e.time - base:.3f}" if e.time is not None and base is not None else "-"
            table.add_row(Text(str(e.frame), justify="right"), Text(when, justify="right"),
                          Text(e.kind, style=KIND_STYLE.get(e.kind, "")), f"{e.sender[0]}/{e.sender[1]}",
                          text(e.text), key=str(i))
        counts = ", ".join(f"{k} {n}" for k, n in self.counts.items()) or "none"
        dropped = "; not listed: " + ", ".join(f"{k} {n}" for k, n in self.dropped.items()) if self.dropped else ""
        self.query_one("#events-title", Label).update(
            Text(f"{len(events)} events ({counts}{dropped}){cut}.  Enter: go to the event's frame"))
        table.focus()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        events: list[Event] = self.result  # type: ignore[assignment]
        if event.row_key.value is None:
            return
        e = events[int(event.row_key.value)]
        self.dismiss(None)
        self.app.goto_record(e.frame)  # type: ignore[attr-defined]
