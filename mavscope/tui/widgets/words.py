"""The TUI's widgets for words a capture or a dialect chose: a table, a label and a pane that never take a
string for markup and show it escaped (`mavscope.output.console.text`: control, format and bidi characters
and the backslash as `visible` writes them).

Textual reads a `str` given to a DataTable cell, a Label or a Static as markup (`[blink red]` would blink)
and writes its control characters to the terminal as they are (an OSC 52 would set the clipboard). The
screens build their tables and texts with these instead: a `str` becomes an escaped Text, a rich Text (which
the screens make with `console.text` or of their own words) is shown as it is. Their CSS type names are
DataTable, Label and Static still (Textual matches a widget's base classes too).
"""

from __future__ import annotations

from typing import Any

from rich.console import RenderableType
from rich.text import Text
from textual.widgets import DataTable, Label, Static

from mavscope.output.console import text

__all__ = ["Pane", "Table", "Title", "cell"]


def cell(value: Any) -> Any:
    """A table cell or a text: a `str` as an escaped Text, anything else as it is."""
    return text(value) if isinstance(value, str) else value


class Table(DataTable[Any]):
    """A DataTable whose `str` headings and cells are escaped Text."""

    def add_column(self, label: Any, *args: Any, **kwargs: Any) -> Any:
        return super().add_column(cell(label), *args, **kwargs)

    def add_columns(self, *columns: Any) -> Any:
        return super().add_columns(*(c if isinstance(c, tuple) else cell(c) for c in columns))

    def add_row(self, *cells: Any, **kwargs: Any) -> Any:
        return super().add_row(*(cell(c) for c in cells), **kwargs)

    def update_cell(self, row_key: Any, column_key: Any, value: Any, **kwargs: Any) -> None:
        super().update_cell(row_key, column_key, cell(value), **kwargs)

    def update_cell_at(self, coordinate: Any, value: Any, **kwargs: Any) -> None:
        super().update_cell_at(coordinate, cell(value), **kwargs)


class Pane(Static):
    """A Static that shows a `str` escaped, never as markup (any other renderable as it is)."""

    def __init__(self, content: RenderableType = "", **kwargs: Any) -> None:
        kwargs["markup"] = False
        super().__init__(cell(content), **kwargs)

    def update(self, content: Any = "", *, layout: bool = True) -> None:
        super().update(cell(content), layout=layout)


class Title(Label):
    """A Label that shows a `str` escaped, never as markup."""

    def __init__(self, content: Text | str = "", **kwargs: Any) -> None:
        kwargs["markup"] = False
        super().__init__(cell(content), **kwargs)

    def update(self, content: Any = "", *, layout: bool = True) -> None:
        super().update(cell(content), layout=layout)
