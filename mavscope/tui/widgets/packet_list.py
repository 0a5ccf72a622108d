"""The packet list: one line per frame, drawn straight from the index, only for the visible window.

A Line API widget (as toolong's log view): nothing per row exists until the row is on screen, so a
million frames cost nothing here. Textual's DataTable builds an object per row and cell: adding 200k
rows took it minutes (docs/tui.md). The first line is a fixed header; the cursor is a position in the
current view (every indexed frame, or the rows a display filter kept).
"""

from __future__ import annotations

from bisect import bisect_left
from collections import OrderedDict
from collections.abc import Sequence

from rich.segment import Segment
from rich.style import Style
from textual.binding import Binding
from textual.events import Click
from textual.geometry import Size
from textual.message import Message
from textual.reactive import reactive
from textual.scroll_view import ScrollView
from textual.strip import Strip

from mavscope.browse.index import FrameIndex
from mavscope.browse.rows import Row
from mavscope.mavlink.frame import CrcStatus
from mavscope.mavlink.semantics import message_label
from mavscope.tui.verdicts import (
    CRC_GLYPHS,
    ENCRYPTION_GLYPHS,
    RED,
    SIGNATURE_GLYPHS,
    encryption_key,
    signature_key,
)
from mavscope.visible import printable, visible

# (title, width); the last column takes the rest of the line
COLUMNS: tuple[tuple[str, int], ...] = (
    ("No.", 9), ("Time", 11), ("Source", 22), ("Sys/Comp", 9), ("Seq", 4), ("Message", 24), ("CSE", 4),
    ("Info", 0),
)


def _cell(text: str, width: int, right: bool = False) -> str:
    if len(text) > width - 1:
        text = text[: width - 2] + "…" if width > 2 else text[:width]
        return text.ljust(width)
    return (text.rjust(width - 1) + " ") if right else text.ljust(width)


class PacketList(ScrollView, can_focus=True):
    """The frames of the capture (or of the filtered view), one per line."""

    BINDINGS = [
        Binding("up", "cursor(-1)", "Up", show=False),
        Binding("down", "cursor(1)", "Down", show=False),
        Binding("pageup", "page(-1)", "Page up", show=False),
        Binding("pagedown", "page(1)", "Page down", show=False),
        Binding("home", "home", "First", show=False),
        Binding("end", "end", "Last", show=False),
        Binding("enter", "activate", "Details", show=False),
    ]
    COMPONENT_CLASSES = {"packet-list--header", "packet-list--cursor", "packet-list--cursor-blurred"}
    DEFAULT_CSS = """
    PacketList { overflow-x: hidden; }
    PacketList > .packet-list--header { text-style: bold; background: $panel; }
    PacketList > .packet-list--cursor { background: $accent 60%; }
    PacketList > .packet-list--cursor-blurred { background: $accent 25%; }
    """

    cursor: reactive[int] = reactive(-1, always_update=False, repaint=False)

    class Highlighted(Message):
        """The cursor moved to another frame (`row` is its row number, or None when the view is empty).

        A bounded live index may drop that row before the message is handled: the handler then finds
        it gone (IndexError), and the line's move that followed the drop has posted another message."""

        def __init__(self, row: int | None) -> None:
            super().__init__()
            self.row = row

    class Activated(Message):
        """Enter (or a double click) on a frame."""

        def __init__(self, row: int) -> None:
            super().__init__()
            self.row = row

    def __init__(self, index: FrameIndex, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.index = index
        self.view: Sequence[int] | None = None  # None: every indexed row
        self._base = index.first  # without a view: the row number of the first line
        self._skip = 0  # with a view: its entries naming rows the index has dropped since
        self._count = 0
        self._strips: OrderedDict[tuple[int, int, int], Strip] = OrderedDict()

    # --- model --------------------------------------------------------------------------------

    @property
    def count(self) -> int:
        """Lines in the current view."""
        return self._count

    def row_at(self, position: int) -> int:
        """The row number of line `position`."""
        return self._base + position if self.view is None else self.view[self._skip + position]

    def _lines(self) -> int:
        return self.index.end - self._base if self.view is None else len(self.view) - self._skip

    @property
    def cursor_row(self) -> int | None:
        """The index row under the cursor."""
        return self.row_at(self.cursor) if 0 <= self.cursor < self._count else None

    def set_index(self, index: FrameIndex) -> None:
        """Show another index of the same capture (after a key was added): same rows, new verdicts."""
        self.index = index
        self._base = index.first
        self.redraw()
        self.sync()

    def redraw(self) -> None:
        """The rows' verdicts changed (judged again with new keys): draw every line anew."""
        self._strips.clear()
        self.refresh()

    def set_view(self, view: Sequence[int] | None, keep_row: int | None = None) -> None:
        """Show `view` (index rows, ascending; None for all); the cursor goes to `keep_row` or the nearest."""
        self.view = view
        self._strips.clear()
        self._base = self.index.first
        self._skip = 0 if view is None else bisect_left(view, self.index.first)
        self._count = self._lines()
        self._update_size()
        target = 0
        if keep_row is not None and self._count:
            target = self.position_of(keep_row)
        self.cursor = -1  # always post a Highlighted for the new view
        self.cursor = target if self._count else -1
        self.refresh()

    def sync(self, follow: bool = False) -> None:
        """The index or the view grew: take in the new lines (the cursor goes to the first line if unset;
        with `follow`, a cursor on the last line stays on the last line, as `tail -f`)."""
        n = self._lines()
        if follow and n and self.cursor == self._count - 1 and n != self._count:
            self._count = n
            self._update_size()
            self.cursor = n - 1
            return
        if n != self._count:
            self._count = n
            self._update_size()
            self.refresh()
        if self.cursor < 0 and n:
            self.cursor = 0
        elif self.cursor >= 0:
            self.refresh()

    @property
    def stale(self) -> bool:
        """The index dropped rows that this list still shows as lines (see `drop_lines`)."""
        return self.index.first != self._base if self.view is None else bool(
            len(self.view) > self._skip and self.view[self._skip] < self.index.first)

    def drop_lines(self) -> None:
        """Take out the lines of the rows the bounded index dropped: the cursor stays on its frame, on
        the first line if that frame went, or on the last line if it was there (following)."""
        old_row = self.cursor_row
        was_last = self.cursor == self._count - 1
        first = self.index.first
        if self.view is None:
            self._base = first
        else:
            self._skip = bisect_left(self.view, first, self._skip)
        self._count = self._lines()
        self._update_size()
        self.refresh()
        if not self._count:
            self.cursor = -1
            return
        if self.cursor < 0:
            return
        target = self._count - 1 if was_last or old_row is None else self.position_of(old_row)
        if target == self.cursor and self.cursor_row != old_row:
            self.post_message(self.Highlighted(self.cursor_row))  # same line, another frame
        self.cursor = target

    def position_of(self, row: int) -> int:
        """The line of `row`, or of the next row shown (the last line if none)."""
        if self.view is None:
            return max(0, min(row - self._base, self._count - 1))
        return max(0, min(bisect_left(self.view, row, self._skip) - self._skip, self._count - 1))

    def _update_size(self) -> None:
        self.virtual_size = Size(self.size.width, self._count + 1)

    def on_resize(self) -> None:
        self._strips.clear()
        self._update_size()
        self.call_after_refresh(self._reveal_cursor)

    def _reveal_cursor(self) -> None:
        new = self.cursor
        if new >= 0:
            top = round(self.scroll_y)
            if new < top:
                self.scroll_to(y=new, animate=False)
            elif new >= top + self.page:
                self.scroll_to(y=new - self.page + 1, animate=False)

    # --- cursor -------------------------------------------------------------------------------

    @property
    def page(self) -> int:
        return max(1, self.scrollable_content_region.height - 1)

    def watch_cursor(self, old: int, new: int) -> None:
        self._reveal_cursor()
        self.refresh()
        self.post_message(self.Highlighted(self.cursor_row))

    def move_to(self, position: int) -> None:
        if self._count:
            self.cursor = max(0, min(self._count - 1, position))

    def action_cursor(self, delta: int) -> None:
        self.move_to(self.cursor + delta)

    def action_page(self, direction: int) -> None:
        self.move_to(self.cursor + direction * self.page)

    def action_home(self) -> None:
        self.move_to(0)

    def action_end(self) -> None:
        self.move_to(self._count - 1)

    def action_activate(self) -> None:
        row = self.cursor_row
        if row is not None:
            self.post_message(self.Activated(row))

    def on_click(self, event: Click) -> None:
        offset = event.get_content_offset(self)
        if offset is None or offset.y == 0:
            return
        position = round(self.scroll_y) + offset.y - 1
        if 0 <= position < self._count:
            self.cursor = position
            if event.chain == 2:
                self.action_activate()

    def on_focus(self) -> None:
        self.refresh()

    def on_blur(self) -> None:
        self.refresh()

    # --- rendering ----------------------------------------------------------------------------

    def visible_rows(self) -> list[int]:
        """Index rows of the lines on screen (for tests and the status bar)."""
        top = round(self.scroll_y)
        return [self.row_at(p) for p in range(top, min(self._count, top + self.page))]

    def render_line(self, y: int) -> Strip:
        width = self.size.width
        base = self.rich_style
        if y == 0:
            header = "".join(_cell(t, w, right=t in ("No.", "Time", "Seq")) if w else t for t, w in COLUMNS)
            style = base + self.get_component_rich_style("packet-list--header")
            return Strip([Segment(header, style)]).crop_extend(0, width, style)
        position = round(self.scroll_y) + y - 1
        if not 0 <= position < self._count:
            return Strip.blank(width, base)
        row = self.row_at(position)
        state = 0 if position != self.cursor else (2 if self.has_focus else 1)
        key = (row, width, state)
        strip = self._strips.get(key)
        if strip is None:
            try:
                strip = self._render_row(row, width, state, base)
            except IndexError:  # the bounded live index dropped this row: drop_lines comes next
                return Strip.blank(width, base)
            self._strips[key] = strip
            if len(self._strips) > 512:
                self._strips.popitem(last=False)
        return strip

    def _render_row(self, row: int, width: int, state: int, base: Style) -> Strip:
        r: Row = self.index.row(row)
        if state:
            base = base + self.get_component_rich_style(
                "packet-list--cursor" if state == 2 else "packet-list--cursor-blurred")
        t0 = self.index.time_base
        t = "-" if r.time is None or t0 is None else f"{r.time - t0:.6f}"
        src = str(r.src or r.transport)
        label = visible(r.msgname) if r.msgname else message_label(r.msgid, None)  # (as the Info column has it)
        segs = [
            Segment(_cell(r.number, COLUMNS[0][1], True), base),
            Segment(_cell(t, COLUMNS[1][1], True), base),
            Segment(_cell(src, COLUMNS[2][1]), base),
            Segment(_cell(f"{r.sysid}/{r.compid}", COLUMNS[3][1]), base),
            Segment(_cell(str(r.seq), COLUMNS[4][1], True), base),
            Segment(_cell(label, COLUMNS[5][1]), base),
        ]
        glyph, style, _ = CRC_GLYPHS[r.crc_status]
        segs.append(Segment(glyph, base + Style.parse(style)))
        sk = signature_key(r.incompat_flags, r.security)
        if sk is None:
            segs.append(Segment(" ", base))
        else:
            glyph, style, _ = SIGNATURE_GLYPHS.get(sk, ("?", "", ""))
            segs.append(Segment(glyph, base + Style.parse(style)))
        ek = encryption_key(r.incompat_flags, r.encryption_status)
        if ek is None:
            segs.append(Segment(" ", base))
        else:
            glyph, style, _ = ENCRYPTION_GLYPHS.get(ek, ("?", "", ""))
            segs.append(Segment(glyph, base + Style.parse(style)))
        segs.append(Segment(" ", base))
        info = printable(self.index.summary(row))  # (its words escaped as it was made: fields/summary.py)
        if info.startswith(label):
            info = info[len(label) :].lstrip()  # the Message column has it
        bad = r.crc_status in (CrcStatus.BAD, CrcStatus.TRUNCATED) or sk in ("invalid",)
        segs.append(Segment(info, base + Style.parse(RED) if bad else base))
        return Strip(segs).crop_extend(0, width, base)
