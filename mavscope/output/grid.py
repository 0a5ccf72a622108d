"""Every table a command prints: rich's bordered table for what fits on a few screens, plain columns streamed
for more.

rich lays a table out whole before it writes a line: about 0.5 ms and 13 KB a row, so `commands` on a
capture of 200,000 unanswered commands took 212 s and 2.7 GB. The capture decides how many rows a table has
(commands, links, parameter changes, mission items, events), so past RICH_ROWS rows the table is written as
plain columns instead: a first pass over the rows finds each column's width, a second writes one line a row
as it goes. Time is linear in the rows and memory is that of one row.

In the plain layout a column is padded to at most PAD_LIMIT cells: a longer cell runs on into the rest of its
line (never cut, nothing hidden), and one long cell cannot widen every line of the output. Cells show what
`visible` shows (a capture's control characters escaped), line breaks escaped too: one row is one line, for
grep and for a reader. Styles (the colour of an event's kind) are rich's alone. rich is imported when a
table is printed (a command writing JSON never loads it).

Lines a command prints one per thing the capture holds (a mission transfer, an unmatched ACK) cost rich
about as much as a row; `print_lines` writes them plain past RICH_ROWS too, and a command printing many
small tables and lines (`mission`) decides once for all of them with `many`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias, TypeVar

if TYPE_CHECKING:
    from rich.text import Text

    Cell: TypeAlias = str | Text

RICH_ROWS = 1000  # rows a table has at most in rich's layout
PAD_LIMIT = 48  # cells a plain column is padded to at most
_CHUNK = 512  # lines written at once in the plain layout

T = TypeVar("T")


@dataclass(frozen=True, slots=True)
class Column:
    """A column: its heading, right-aligned (numbers) or not, and for rich's layout whether a long cell folds
    onto more lines (a path, an SQL value) rather than ending in an ellipsis, and a width it keeps."""

    name: str
    right: bool = False
    fold: bool = False
    min_width: int | None = None


def columns(*names: str, right: Sequence[str] = ()) -> list[Column]:
    """Columns by name, those named in `right` right-aligned."""
    return [Column(n, right=n in right) for n in names]


def many(rows: int) -> bool:
    """Whether output of `rows` rows and lines is written plain."""
    return rows > RICH_ROWS


def print_table(con: Any, cols: Sequence[Column], items: Sequence[T], row: Callable[[T], Sequence[Cell]], *,
                title: Cell = "", edge: bool = True, words: bool = False, plain: bool | None = None) -> None:
    """The table of `items` on the console `con`, a row each as `row` makes it (called once or, in the plain
    layout, twice an item: it must depend on the item alone). No items: the headings alone. `words`: every
    str cell is the capture's words, shown as `console.text` shows them (never highlighted, a line break
    escaped) rather than as rich renders a str. `plain`: the layout (None: plain past RICH_ROWS rows)."""
    if not (many(len(items)) if plain is None else plain):
        _rich(con, cols, items, row, title, edge, words)
    else:
        _plain(con, cols, items, row, title)


def print_lines(con: Any, lines: Iterable[str], *, plain: bool) -> None:
    """Lines of text, each shown as `visible` shows it: by rich (wrapped to the console's width, never
    highlighted), or `plain`, written as they are in chunks of _CHUNK lines."""
    if not plain:
        for line in lines:
            con.print(line, highlight=False)
        return
    from mavscope.output.console import visible

    _write(con, (visible(line) for line in lines))


def _write(con: Any, lines: Iterable[str]) -> None:
    """Lines to the console's file, _CHUNK at a time."""
    write = con.file.write
    chunk: list[str] = []
    for line in lines:
        chunk.append(line)
        if len(chunk) >= _CHUNK:
            write("\n".join(chunk) + "\n")
            chunk.clear()
    if chunk:
        write("\n".join(chunk) + "\n")
    con.file.flush()


def _rich(con: Any, cols: Sequence[Column], items: Sequence[T], row: Callable[[T], Sequence[Cell]], title: Cell,
          edge: bool, words: bool) -> None:
    from rich.table import Table

    from mavscope.output.console import text

    t = Table(title=(text(title) if isinstance(title, str) else title) if title else None, title_justify="left",
              show_edge=edge)
    for c in cols:
        t.add_column(text(c.name), justify="right" if c.right else "left", min_width=c.min_width,
                     overflow="fold" if c.fold else "ellipsis")
    for item in items:
        cells = row(item)
        t.add_row(*((text(c) if isinstance(c, str) else c for c in cells) if words else cells))
    con.print(t)


def _plain(con: Any, cols: Sequence[Column], items: Sequence[T], row: Callable[[T], Sequence[Cell]],
           title: Cell) -> None:
    from rich.cells import cell_len

    from mavscope.output.console import visible

    def _cell(c: Cell) -> str:
        return visible(c) if isinstance(c, str) else c.plain

    heads = [visible(c.name) for c in cols]
    widths = [min(PAD_LIMIT, cell_len(h)) for h in heads]
    for item in items:
        for j, c in enumerate(row(item)):
            n = cell_len(_cell(c))
            if n > widths[j]:
                widths[j] = min(PAD_LIMIT, n)
    last = len(cols) - 1

    def line(cells: Sequence[str]) -> str:
        out = []
        for j, s in enumerate(cells):
            pad = widths[j] - cell_len(s)
            if pad <= 0 or (j == last and not cols[j].right):
                out.append(s)
            else:
                out.append(" " * pad + s if cols[j].right else s + " " * pad)
        return "  ".join(out).rstrip()

    head = [_cell(title)] if title else []
    _write(con, (*head, line(heads), line(["-" * w for w in widths])))
    _write(con, (line([_cell(c) for c in row(item)]) for item in items))
