"""The rich Console the commands write text through, safe for words a capture chose.

A capture decides many strings the text output shows: STATUSTEXT, parameter and file names, SQL cells, the
names of capture files themselves. Written as they are, an escape sequence among them reaches the analyst's
terminal (colours, concealed text, an OSC 8 hyperlink, a new window title), and rich would take a name in
square brackets for markup (`[fe80::1]:14550` lost its address). So:

- no markup anywhere (`markup=False`): the commands never style text with it;
- a line the commands `print` shows its control and format characters escaped as Python's `repr` writes
  them (`visible`), line breaks too: a STATUSTEXT or a file name cannot start a line that looks like one of
  ours; a table cell given as `str` likewise, its line breaks kept (they stay inside the cell);
- strings from the capture in a table cell or a title go through `text()`, a rich Text escaped the same
  way. The commands make no `Text` of their own (tests/cli/test_output_safety.py checks).
"""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.text import Text

from mavscope.visible import visible

__all__ = ["SafeConsole", "text", "visible"]


def text(s: str, style: str = "") -> Text:
    """A capture's string as a rich Text: no markup, every non-printable character escaped (`visible`)."""
    return Text(visible(s), style=style)


class SafeConsole(Console):
    """A rich Console that shows no markup and escapes what `visible` escapes in every string it renders."""

    def __init__(self, **kwargs: Any) -> None:
        kwargs["markup"] = False
        super().__init__(**kwargs)

    def print(self, *objects: Any, **kwargs: Any) -> None:
        super().print(*(text(o) if isinstance(o, str) else o for o in objects), **kwargs)

    def render_str(self, text: str, **kwargs: Any) -> Text:
        kwargs["markup"] = False
        return super().render_str(visible(text, keep_newlines=True), **kwargs)
