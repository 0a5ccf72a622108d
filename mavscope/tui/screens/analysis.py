"""What the statistics, mission and expert screens share: run an analysis over the frames in a
thread worker (with progress and cancellation on close), then show the result.

The analysis runs over every frame of the index (rebuilt one by one, never all held at once); under a
display filter the rows of the packet list's view are the selection, as `mavscope stats -Y` reports
the rows with a matched frame (`mavscope.analysis.selection`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import TypeVar

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Footer, Static
from textual.worker import get_current_worker

from mavscope.analysis.selection import Selection
from mavscope.browse.index import FrameIndex
from mavscope.mavlink.frame import Frame
from mavscope.tui.widgets.words import Pane

TABLE_ROWS = 5_000  # rows a screen's table lists: Textual laid out 200,000 mission transfers for 30 s
T = TypeVar("T")


def first_rows(items: list[T], command: str) -> tuple[list[T], str]:
    """The items a table lists (the first TABLE_ROWS) and, when that is not all of them, what its title adds."""
    if len(items) <= TABLE_ROWS:
        return items, ""
    return items[:TABLE_ROWS], (f" (the first {TABLE_ROWS:,} of {len(items):,} listed: `mavscope {command} --json`"
                                " has them all)")


class _Cancelled(Exception):
    pass


class AnalysisScreen(Screen[None]):
    """Subclasses implement `analyse(frames)` (in a thread) and `show(result)` (in the UI)."""

    TITLE_TEXT = ""
    BINDINGS = [
        Binding("escape", "dismiss", "Back"),
        Binding("q", "dismiss", "Back", show=False),
    ]
    DEFAULT_CSS = """
    AnalysisScreen #analysis-status { height: auto; padding: 0 1; color: $text-muted; }
    AnalysisScreen #analysis-body { height: 1fr; }
    """

    class Done(Message):
        def __init__(self, result: object) -> None:
            super().__init__()
            self.result = result

    class Step(Message):
        def __init__(self, done: int, total: int) -> None:
            super().__init__()
            self.done = done
            self.total = total

    def __init__(self, index: FrameIndex, rows: Sequence[int] | None) -> None:
        super().__init__()
        self.index = index
        self.rows = rows
        self.result: object = None
        self.selection = Selection()  # what the analysis marked as shown (set by run_analysis)

    def compose(self) -> ComposeResult:
        yield Pane(self._scope() + "  analysing…", id="analysis-status")
        with Vertical(id="analysis-body"):
            yield from self.compose_body()
        yield Footer()

    def compose_body(self) -> ComposeResult:
        yield from ()

    def _scope(self) -> str:
        n = len(self.index)
        what = "all frames" if self.rows is None else f"rows with one of the {len(self.rows):,} frames the filter shows"
        partial = "" if self.index.done else " (the index is still being built: frames so far)"
        return f"{self.TITLE_TEXT}: {n:,} frames, {what}{partial}"

    def on_mount(self) -> None:
        self.sub_title = self.TITLE_TEXT
        self.run_analysis()

    @work(thread=True, exclusive=True, group="analysis", exit_on_error=False)
    def run_analysis(self) -> None:
        worker = get_current_worker()
        rows = self.index.rows()
        total = len(rows)
        selection = self.selection = Selection(active=self.rows is not None)

        def frames() -> Iterator[Frame]:
            """Every frame held, marking those in the view (both row lists ascend: one walk)."""
            view = self.rows if self.rows is not None else ()
            v = 0
            for i, n in enumerate(rows):
                if not i & 0x3FFF:
                    if worker.is_cancelled:
                        raise _Cancelled
                    self.post_message(self.Step(i, total))
                try:
                    f = self.index.frame(n)
                except IndexError:  # dropped by a bounded live index meanwhile
                    continue
                while v < len(view) and view[v] < n:
                    v += 1
                if v < len(view) and view[v] == n:
                    selection.mark(f)
                yield f

        try:
            result = self.analyse(frames(), selection)
        except _Cancelled:
            return
        if not worker.is_cancelled:
            self.post_message(self.Done(result))

    def analyse(self, frames: Iterator[Frame], selection: Selection) -> object:
        """The screen's analysis over every frame; `selection` tells which rows to show."""
        raise NotImplementedError

    def on_analysis_screen_step(self, msg: Step) -> None:
        if msg.total:
            self.query_one("#analysis-status", Static).update(
                f"{self._scope()}  analysing {msg.done / msg.total:.0%}")

    def on_analysis_screen_done(self, msg: Done) -> None:
        self.result = msg.result
        self.query_one("#analysis-status", Static).update(self._scope() + "  (Escape: back)")
        self.show(msg.result)

    def show(self, result: object) -> None:
        raise NotImplementedError

    def on_unmount(self) -> None:
        self.workers.cancel_group(self, "analysis")
