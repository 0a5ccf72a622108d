"""The hex pane: the selected frame's bytes, the bytes of the field selected in the tree highlighted.

Clicking a byte (or moving the byte cursor with the arrow keys while the pane has focus) selects the
field that covers it in the tree. Same layout as `mavscope read -x` (output.text.hexdump).
"""

from __future__ import annotations

from rich.text import Text
from textual.binding import Binding
from textual.events import Click
from textual.message import Message
from textual.reactive import reactive
from textual.widget import Widget

WIDTH = 16
HEX_START = 6  # "0000  "
ASCII_START = HEX_START + WIDTH * 3 + 2  # hex part is 49 cells wide, then a space


def byte_column(k: int) -> int:
    """Cell of byte `k` (0..15) of a line in the hex part."""
    return HEX_START + 3 * k + (1 if k >= 8 else 0)


def byte_at(x: int, y: int, size: int) -> int | None:
    """The byte under cell (x, y) of the dump of `size` bytes, or None."""
    k: int | None = None
    if HEX_START <= x < ASCII_START - 1:
        rel = x - HEX_START
        k = rel // 3 if rel < 24 else (rel - 1) // 3
        k = min(k, WIDTH - 1)
    elif ASCII_START <= x < ASCII_START + WIDTH:
        k = x - ASCII_START
    if k is None:
        return None
    b = y * WIDTH + k
    return b if 0 <= b < size else None


class HexView(Widget, can_focus=True):
    """Hex dump of one frame with a highlighted byte range."""

    BINDINGS = [
        Binding("left", "move(-1)", "Byte left", show=False),
        Binding("right", "move(1)", "Byte right", show=False),
        Binding("up", "move(-16)", "Byte up", show=False),
        Binding("down", "move(16)", "Byte down", show=False),
    ]
    DEFAULT_CSS = """
    HexView { height: auto; padding: 0 1; }
    """

    data: reactive[bytes] = reactive(b"", layout=True)
    highlight: reactive[tuple[int, int]] = reactive((0, 0))
    cursor: reactive[int] = reactive(-1)

    class ByteSelected(Message):
        """The user chose byte `byte` of the frame."""

        def __init__(self, byte: int) -> None:
            super().__init__()
            self.byte = byte

    def show(self, data: bytes) -> None:
        self.data = data
        self.highlight = (0, 0)
        self.cursor = -1

    def set_highlight(self, offset: int, length: int) -> None:
        self.highlight = (offset, length)

    def render(self) -> Text:
        data = self.data
        if not data:
            return Text("no frame selected", style="dim")
        start, length = self.highlight
        end = start + length
        cur = self.cursor
        out = Text(no_wrap=True, overflow="crop")
        for off in range(0, len(data), WIDTH):
            if off:
                out.append("\n")
            out.append(f"{off:04x}  ", style="dim")
            chunk = data[off : off + WIDTH]
            for k, b in enumerate(chunk):
                style = _style(off + k, start, end, cur)
                out.append(f"{b:02x}", style=style)
                out.append("  " if k == 7 else " ", style=style if start <= off + k + 1 < end and k != 15 else "")
            out.append("   " * (WIDTH - len(chunk)) + (" " if len(chunk) <= 8 else ""))
            out.append(" ")
            for k, b in enumerate(chunk):
                out.append(chr(b) if 32 <= b < 127 else ".", style=_style(off + k, start, end, cur))
        return out

    def on_click(self, event: Click) -> None:
        offset = event.get_content_offset(self)
        if offset is None:
            return
        b = byte_at(offset.x, offset.y, len(self.data))
        if b is not None:
            self.focus()
            self.cursor = b
            self.post_message(self.ByteSelected(b))

    def action_move(self, delta: int) -> None:
        if not self.data:
            return
        b = self.cursor if self.cursor >= 0 else self.highlight[0]
        b = max(0, min(len(self.data) - 1, b + delta))
        self.cursor = b
        self.post_message(self.ByteSelected(b))


def _style(b: int, start: int, end: int, cursor: int) -> str:
    if b == cursor:
        return "reverse bold"
    if start <= b < end:
        return "black on #d7af5f"
    return ""
