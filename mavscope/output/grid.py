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

Nothing rich lays out is cut: every column folds a cell too long for it onto more lines (never an
ellipsis). Written to a file or a pipe, a table is as wide as its widest cells (the console is widened for
it): no cell is wrapped. On a terminal (or at the width $COLUMNS asks for) its key columns (frame numbers,
times, system/component, message and command names, verdicts: `Column.key`, and by name in `columns`) keep
the width of their widest cell and never wrap; the other columns share what is left, each at least KEEP
cells (or its widest cell), folding their cells. A table whose key columns cannot fit so is written in the
plain layout instead (one line a row, uncut: the terminal wraps it).

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


KEEP = 5  # cells a column that is not a key keeps at least where a table fits a width (if its cells are as wide)
# the columns of the commands' tables that are keys by their name (frames, times, parties, names, verdicts)
KEY_NAMES = frozenset({"frame", "#", "seq", "time", "start", "from", "to", "from -> to", "sysid/compid", "comp",
                       "message", "command", "result", "kind", "severity", "code", "status", "clock",
                       "parameter", "transport", "signature", "valid", "invalid", "replay", "injected"})


@dataclass(frozen=True, slots=True)
class Column:
    """A column: its heading, right-aligned (numbers) or not; `key`: kept whole on a terminal (never wrapped,
    as wide as its widest cell); `fold` is kept for its callers (every column folds: nothing is cut); a
    width it keeps at least."""

    name: str
    right: bool = False
    fold: bool = False
    min_width: int | None = None
    key: bool = False


def columns(*names: str, right: Sequence[str] = ()) -> list[Column]:
    """Columns by name, those named in `right` right-aligned, those in KEY_NAMES key columns."""
    return [Column(n, right=n in right, key=n in KEY_NAMES) for n in names]


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
        if _rich(con, cols, items, row, title, edge, words):
            return
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


def _fit_width(con: Any) -> bool:
    """Whether tables fit the console's width (a terminal, or $COLUMNS asked: mavscope.output.tables.console)
    rather than take the width of their cells (a file or a pipe)."""
    fit = getattr(con, "fit_width", None)
    if fit is not None:
        return bool(fit)
    try:
        return bool(con.file.isatty())
    except (AttributeError, ValueError):
        return False


def _rich(con: Any, cols: Sequence[Column], items: Sequence[T], row: Callable[[T], Sequence[Cell]], title: Cell,
          edge: bool, words: bool) -> bool:
    """The table in rich's layout; False (nothing written) where its key columns cannot fit the terminal."""
    from rich.cells import cell_len
    from rich.table import Table

    from mavscope.output.console import text, visible

    rows = [[(text(c) if isinstance(c, str) else c) if words else c for c in row(item)] for item in items]

    def width(c: Cell) -> int:  # the widest line of a cell as rich shows it
        shown = visible(c, keep_newlines=True) if isinstance(c, str) else c.plain
        return max((cell_len(line) for line in shown.split("\n")), default=0)

    widest = [max(width(text(c.name)), c.min_width or 0, *(width(r[j]) for r in rows if j < len(r)))
              for j, c in enumerate(cols)]
    terminal = _fit_width(con)
    border = (len(cols) + 1) if edge else max(0, len(cols) - 1)
    padding = 2 * len(cols)
    if terminal:
        keep = [w if c.key else min(w, max(KEEP, c.min_width or 0)) for c, w in zip(cols, widest)]
        if sum(keep) + border + padding > con.width:
            return False
    t = Table(title=(text(title) if isinstance(title, str) else title) if title else None, title_justify="left",
              show_edge=edge)
    for c, w in zip(cols, widest):
        kept = w if c.key else min(w, max(KEEP, c.min_width or 0)) if terminal else w
        t.add_column(text(c.name), justify="right" if c.right else "left", min_width=kept or None,
                     no_wrap=c.key or not terminal, overflow="fold")
    for cells in rows:
        t.add_row(*cells)
    full = sum(widest) + border + padding
    if terminal or full <= con.width:
        con.print(t)
        return True
    saved = con.width  # a file or a pipe: the table as wide as its cells, none wrapped
    con.width = full
    try:
        con.print(t)
    finally:
        con.width = saved
    return True


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
