"""`p`: the field selected in the detail tree over time (mavscope.analysis.series, as `mavscope plot`): per
interval the range from minimum to maximum, drawn with braille dots; redrawn to fit when the terminal
changes size. Only the frames of the field's messages are rebuilt from the index (picked by message id)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

from textual.app import ComposeResult
from textual.widgets import Static

from mavscope.analysis.selection import Selection
from mavscope.analysis.series import Plotter
from mavscope.browse.index import FrameIndex
from mavscope.fields.registry import FieldRegistry, PayloadField
from mavscope.mavlink.frame import Frame
from mavscope.output.console import text
from mavscope.output.plotting import chart
from mavscope.tui.screens.analysis import AnalysisScreen
from mavscope.tui.widgets.words import Pane


class PlotScreen(AnalysisScreen):
    TITLE_TEXT = "Plot"
    DEFAULT_CSS = """
    PlotScreen #plot { height: 1fr; padding: 0 1; }
    """

    def __init__(self, index: FrameIndex, rows: Sequence[int] | None, field: str) -> None:
        super().__init__(index, rows)
        self.field = field
        self.plotter = Plotter(FieldRegistry(index.dialect), [field])  # UsageError for a field that is no number

    def compose_body(self) -> ComposeResult:
        yield Pane(text(f"{self.field} over time"), id="plot")

    def analyse(self, frames: Iterator[Frame], selection: Selection) -> Plotter:
        """Over the frames of the field's messages (the filter's view when there is one)."""
        found = FieldRegistry(self.index.dialect).lookup(self.field.partition("[")[0])
        rows = self.rows if self.rows is not None else self.index.rows()
        if isinstance(found, PayloadField):
            ids = set(found.defs)
            rows = [r for r, m in zip(rows, self.index.column("msgid", rows)) if m in ids]
        for f in self.index.frames(rows):
            self.plotter.add(f)
        return self.plotter

    def show(self, result: object) -> None:
        self.redraw()

    def on_resize(self) -> None:
        if self.result is not None:
            self.redraw()

    def redraw(self) -> None:
        plot = self.query_one("#plot", Static)
        width, height = max(20, plot.size.width - 2), max(4, plot.size.height - 3)
        series = self.plotter.series[0]
        plot.update(chart(series, width, height, self.plotter.x_label or "s"))
