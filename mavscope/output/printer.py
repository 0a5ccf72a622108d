"""Per-frame output shared by `read` and `live`: summary lines, -V tree, -x hex, JSON Lines, JSON array.

One `FramePrinter` per run: `begin()`, then `frame(f)` per frame shown, then `end()`. The caller decides
which frames are shown (filters, -c); the printer only decides how they look.
"""

from __future__ import annotations

from typing import IO

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.output.colour import RESET, line_colour
from mavscope.output.jsonout import jsonl_bytes
from mavscope.output.text import detail_text, hexdump, summary_line
from mavscope.output.timefmt import Clock


class FramePrinter:
    """Writes frames as text (`out`) or JSON (`out_b`, the same stream's bytes): "text", "json" or "jsonl"
    (`quiet`: nothing per frame)."""

    def __init__(
        self,
        out: IO[str],
        out_b: IO[bytes],
        dialect: Dialect,
        fmt: str = "text",
        *,
        verbose: bool = False,
        hex: bool = False,  # noqa: A002 - the option is called -x / hex everywhere else
        quiet: bool = False,
        t0: float | None = None,
        clock: Clock | None = None,
        colour: bool = False,
    ) -> None:
        self.out = out
        self.out_b = out_b
        self.dialect = dialect
        self.fmt = fmt
        self.verbose = verbose
        self.hex = hex
        self.quiet = quiet
        self.t0 = t0  # relative times in summary lines count from it (None: no relative time)
        self.clock = clock  # read -t's time column (None: relative to t0)
        self.colour = colour  # summary lines coloured by verdict (output.colour)
        self.count = 0  # frames passed to frame()

    def begin(self) -> None:
        if self.fmt == "json":
            self.out_b.write(b"[")

    def frame(self, frame: Frame) -> None:
        self.count += 1
        if self.quiet:
            return
        fmt = self.fmt
        if fmt == "jsonl":
            self.out_b.write(jsonl_bytes(frame))
        elif fmt == "json":
            self.out_b.write((b"\n" if self.count == 1 else b",\n") + jsonl_bytes(frame)[:-1])
        else:
            out = self.out
            when = self.clock.text(frame) if self.clock is not None else None
            line = summary_line(frame, self.dialect, self.t0, time_text=when)
            code = line_colour(frame) if self.colour else None
            out.write(f"{code}{line}{RESET}\n" if code is not None else line + "\n")
            if self.verbose:
                out.write(detail_text(frame, self.dialect) + "\n")
            if self.hex:
                out.write(hexdump(frame.raw) + "\n")
            if self.verbose or self.hex:
                out.write("\n")

    def end(self) -> None:
        if self.fmt == "json":
            self.out_b.write(b"\n]\n" if self.count else b"]\n")

    def flush(self) -> None:
        """Push what was written to the reader (text and bytes share one buffer on real streams)."""
        if self.fmt == "text":
            self.out.flush()
        else:
            self.out_b.flush()
