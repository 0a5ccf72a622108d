"""`?`: every key binding and what the verdict glyphs mean."""

from __future__ import annotations

from rich.table import Table
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import ModalScreen

from mavscope.tui.bindings import KEYS
from mavscope.tui.verdicts import legend
from mavscope.tui.widgets.words import Pane


def help_table() -> Table:
    keys = Table(title="Keys", title_justify="left", box=None, padding=(0, 2), show_header=True,
                 header_style="bold")
    keys.add_column("Key", style="bold cyan", no_wrap=True)
    keys.add_column("Action")
    keys.add_column("Where", style="dim", no_wrap=True)
    for k, what, where in KEYS:
        keys.add_row(k, what, where)
    return keys


def legend_table() -> Table:
    t = Table(title="Verdict column (CSE: CRC, signature, encryption)", title_justify="left", box=None,
              padding=(0, 2), show_header=False)
    t.add_column("Glyph", no_wrap=True)
    t.add_column("Meaning")
    for glyph, style, meaning in legend():
        t.add_row(Text(glyph, style=style), meaning)
    return t


class HelpScreen(ModalScreen[None]):
    BINDINGS = [
        Binding("escape", "dismiss", "Close"),
        Binding("q", "dismiss", "Close", show=False),
        Binding("question_mark", "dismiss", "Close", show=False),
    ]
    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > VerticalScroll { width: 100; max-width: 95%; height: 90%; border: thick $primary;
                                  background: $surface; padding: 0 1; }
    """

    def compose(self) -> ComposeResult:
        with VerticalScroll() as v:
            v.border_title = "mavscope tui: help (Escape closes)"
            yield Pane(help_table())
            yield Pane("")
            yield Pane(legend_table())
            yield Pane(Text("\nRows: No. is the capture record (record.index when a record holds several "
                              "frames); Time is seconds since the first frame.", style="dim"))
