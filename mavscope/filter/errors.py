"""The one error a display filter raises: what is wrong, and where in the text."""

from __future__ import annotations

from mavscope.errors import MavscopeError
from mavscope.visible import visible

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
        return "\n".join(self.lines())

    def lines(self) -> list[str]:
        """The message, the filter's text, and a caret under the problem. White space shows as a space; any
        other character `visible` escapes is left for the writer to escape (a filter may be pasted from
        anywhere: cli.Env.say escapes each line, once), the caret moved to match its escape's width."""
        shown = ["  "]
        for c in self.text:
            shown.append(" " if c in "\t\r\n\v\f" else c)
        widths = [len(visible(c)) for c in shown[1:]]
        end = self.position + self.length
        before = sum(widths[: self.position])
        under = sum(widths[self.position : end]) + max(0, end - len(self.text))
        caret = " " * before + "^" + "~" * (under - 1)
        return [f"filter error: {self.message}", "".join(shown), "  " + caret]
