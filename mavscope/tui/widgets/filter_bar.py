"""The display filter bar: `/` focuses it, Enter applies, Escape goes back to the packet list.

A filter that does not compile stays in the bar: the error is shown under it with a caret at the
position the filter compiler reported, and the text cursor is put there.
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.message import Message
from textual.widget import Widget
from textual.widgets import Input, Static

from mavscope.tui.widgets.words import Pane, Title
from mavscope.visible import visible

PROMPT = "Filter: "


class FilterInput(Input):
    BINDINGS = [Binding("escape", "leave", "Leave the filter bar", show=False)]

    def action_leave(self) -> None:
        self.post_message(FilterBar.Left())


class FilterBar(Widget):
    """Prompt, input and (after a failed Enter) the error line."""

    DEFAULT_CSS = """
    FilterBar { height: auto; }
    FilterBar Horizontal { height: 1; }
    FilterBar Label { width: auto; color: $text-muted; }
    FilterBar Input { border: none; height: 1; padding: 0 0; width: 1fr; background: $boost; }
    FilterBar Input:focus, FilterBar Input.-invalid, FilterBar Input.-invalid:focus { border: none; height: 1;
                                                                            background: $boost; }
    FilterBar.-applied Label { color: $success; text-style: bold; }
    FilterBar.-error Input { background: $error 25%; }
    FilterBar #filter-error { color: $error; height: auto; display: none; }
    FilterBar.-error #filter-error { display: block; }
    """

    class Submitted(Message):
        """Enter in the bar: apply `text` (empty: show every frame)."""

        def __init__(self, text: str) -> None:
            super().__init__()
            self.text = text

    class Left(Message):
        """Escape in the bar."""

    def __init__(self, text: str = "", *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._initial = text
        self.error = ""  # the error line shown under the bar (empty: none)

    def compose(self) -> ComposeResult:
        with Horizontal():
            yield Title(PROMPT)
            yield FilterInput(self._initial, id="filter-input", select_on_focus=False,
                              placeholder="display filter, e.g. COMMAND_LONG or mavlink.crc_status == bad "
                                          "(/ to edit, Enter to apply, Escape to leave)")
        yield Pane("", id="filter-error")

    @property
    def input(self) -> Input:
        return self.query_one(FilterInput)

    @property
    def text(self) -> str:
        return self.input.value

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self.post_message(self.Submitted(event.value.strip()))

    def show_error(self, message: str, position: int, length: int = 1) -> None:
        """Show `message` under the bar with a caret under `position` of the text."""
        caret = " " * (len(PROMPT) + position) + "^" + "~" * max(0, length - 1)
        self.error = f"{caret} {message}"
        self.query_one("#filter-error", Static).update(Text(visible(self.error)))  # (a message may quote the text)
        self.add_class("-error")
        self.input.cursor_position = position
        self.input.focus()

    def clear_error(self) -> None:
        self.error = ""
        self.remove_class("-error")
        self.query_one("#filter-error", Static).update("")

    def set_applied(self, applied: bool) -> None:
        self.set_class(applied, "-applied")
