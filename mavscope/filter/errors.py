"""The one error a display filter raises: what is wrong, and where in the text."""

from __future__ import annotations

from mavscope.errors import MavscopeError

MAX_DEPTH = 64  # parentheses nested deeper than this are refused (no RecursionError on hostile input)


class FilterError(MavscopeError):
    """A display filter that cannot be compiled: the message, and where in the text the problem is."""

    def __init__(self, message: str, text: str, position: int, length: int = 1) -> None:
        self.message = message
        self.text = text
        self.position = max(0, min(position, len(text)))
        self.length = max(1, length)
        super().__init__(self.render())

    def render(self) -> str:
        shown = "".join(" " if c in "\t\r\n\v\f" else c for c in self.text)
        caret = " " * self.position + "^" + "~" * (self.length - 1)
        return f"filter error: {self.message}\n  {shown}\n  {caret}"
