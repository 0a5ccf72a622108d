"""The status line: capture, indexing progress, frames shown, keys in use."""

from __future__ import annotations

from rich.text import Text
from textual.widgets import Static

from mavscope.browse.rows import Progress
from mavscope.visible import visible


def _bar(fraction: float, width: int = 12) -> str:
    full = int(fraction * width)
    return "█" * full + "░" * (width - full)


class StatusBar(Static):
    DEFAULT_CSS = """
    StatusBar { height: 1; background: $panel; color: $text; padding: 0 1; }
    """

    def __init__(self, name: str, *, id: str | None = None) -> None:
        super().__init__("", id=id)
        self.capture = name
        self.progress: Progress | None = None
        self.shown: int | None = None  # frames the filter kept (None: no filter)
        self.filtering: float | None = None  # filter progress while it runs
        self.activity = ""  # another task running ("re-checking with 1 key")
        self.keys = ""
        self.live = False
        self.problems = 0  # problems reading the capture (FrameIndex.problems), shown once it is indexed

    def set_problems(self, frames: int, problems: int, first: str | None) -> str | None:
        """Take the problems reading the capture met (FrameIndex.problems): what the TUI says once it is
        indexed when it held no frame or reading it met problems, as `read` says it on stderr (a damaged
        capture never passes in silence, nor an empty list unexplained); None when there is nothing to say."""
        self.problems = problems
        if not problems and frames:
            return None
        head = f"{problems:,} problem(s) reading the capture" if frames else "no MAVLink frames found in this capture"
        return f"{head}; the first: {first}" if first is not None else head

    def update_status(self) -> None:
        text = Text(visible(self.capture), style="bold")  # (a file name may hold an escape sequence)
        p = self.progress
        if p is not None and self.live:
            text.append(f"  live: {p.frames:,} frames kept", style="green")
        elif p is not None:
            if p.done:
                text.append(f"  {p.frames:,} frames")
                if self.problems:
                    text.append(f", {self.problems:,} problem(s) reading it", style="yellow")
            elif p.cancelled:
                text.append(f"  {p.frames:,} frames (indexing stopped)", style="yellow")
            else:
                text.append(f"  indexing {_bar(p.fraction)} {p.fraction:4.0%}  {p.frames:,} frames so far",
                            style="yellow")
        if self.shown is not None:
            text.append(f"  │  filter: {self.shown:,} shown")
            if self.filtering is not None:
                text.append(f" (filtering {self.filtering:.0%})", style="yellow")
        if self.activity:
            text.append(f"  │  {self.activity}", style="yellow")
        if self.keys:
            text.append(f"  │  {self.keys}")
        text.append("  │  ? help", style="dim")
        self.update(text)
