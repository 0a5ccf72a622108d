"""Presentation helpers for the analysis commands: a rich Console on the command's stdout, sparklines,
number formats, and the JSON writer. The analysis core (mavscope.analysis) never imports this."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from datetime import datetime, timezone
from typing import IO

import orjson

from mavscope.mavlink.semantics import NAN_TEXT, float_text

BARS = "▁▂▃▄▅▆▇█"


def console(out: IO[str], environ: Mapping[str, str]):  # type: ignore[no-untyped-def]
    """A rich Console writing to `out`: colour only on a terminal (as wide as $COLUMNS says where it is set,
    else as the terminal is); written to a file or a pipe, lines as long as they are (never wrapped: one line
    of text is one line for grep) and tables as wide as their cells (mavscope.output.grid), unless $COLUMNS
    asks for a width: then text and tables fit it as on a terminal (folded, never cut). `fit_width` on the
    console says which (mavscope.output.grid reads it). No markup, and a capture's control characters
    escaped (mavscope.output.console)."""
    from mavscope.output.console import SafeConsole as Console

    try:
        tty = out.isatty()
    except (AttributeError, ValueError):
        tty = False
    text = environ.get("COLUMNS", "")
    width = int(text) if text.isascii() and text.isdigit() and int(text) > 0 else None
    if tty:
        con = Console(file=out, emoji=False, width=width)
    else:
        con = Console(file=out, no_color=True, color_system=None, highlight=False, emoji=False,
                      width=width or 160, soft_wrap=width is None)
    setattr(con, "fit_width", tty or width is not None)  # noqa: B010 - an attribute rich's Console lacks
    return con


def sparkline(values: Sequence[float]) -> str:
    """Values as a row of block characters scaled to the largest (a zero as a space): one cell a value.

    The values come already bucketed (`Stats.rate_series`), so the line is as long as asked whatever the
    capture's span."""
    top = max(values, default=0.0)
    if top <= 0:
        return " " * len(values)
    n = len(BARS)
    return "".join(" " if v <= 0 else BARS[min(n - 1, max(0, math.ceil(v / top * n) - 1))] for v in values)


def fmt(value: object, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


SHOWN = 8  # entries of a list a table cell shows


def listed(values: Sequence[object], shown: int = SHOWN) -> str:
    """A list in a table cell: its first `shown` entries and how many more (--json lists them all). A
    capture can make such a list as long as it has frames (a link's endpoints, an item's frames): rich
    wrapped a cell of 200,000 endpoints for 6 s."""
    more = len(values) - shown
    return ", ".join(map(str, values[:shown])) + (f" and {more:,} more (--json lists them)" if more > 0 else "")


PARTIAL_MARK = "*"  # a link whose own frames the capture logs only in part (Stats.logged_in_part)
PARTIAL_TEXT = ("ground station (HEARTBEAT type GCS) in a tlog: a tlog records what the ground station received; "
                "its own frames are logged only in part: this is not link loss")


def partial_line(links: Sequence[Mapping[str, object]]) -> str | None:
    """The line under a Links table (`stats`, the TUI's statistics) that explains the marked rows: the links
    (Stats.links_json rows) logged in part that miss numbers; None when there are none."""
    partial = [f"{lk['sysid']}/{lk['compid']}" for lk in links if lk["logged_in_part"] and lk["lost"]]
    return f"{PARTIAL_MARK} {', '.join(partial)}: {PARTIAL_TEXT}" if partial else None


def param_text(v: object, float32: bool = True) -> str:
    """A command or mission parameter: a float32 (`float32`: the wire's `float`, as param1..7 are) as the
    shortest text that reads back as the same float32 (30.48, not 30.4799995), another float (COMMAND_INT's
    x/y in degrees) as repr; None (a NaN in the frame: JSON carries it as null; PX4 and QGC send NaN for
    "unchanged") as NaN."""
    if v is None:
        return NAN_TEXT
    return float_text(v, float32) if isinstance(v, float) else str(v)


def coord_text(v: float | None, unit: str, float32: bool) -> str:
    """A mission item's x or y: a float32 (MISSION_ITEM's) as the shortest text that reads back as it;
    MISSION_ITEM_INT's degrees to their 7 decimals (degE7), its metres (1e-4 m) as repr, its raw parameter
    (MAV_FRAME_MISSION) as the integer it is. `mission` and the TUI's mission screen both show it so."""
    if v is None:
        return "-"
    if not float32 and unit == "°":
        return f"{v:.7f}°"
    if not float32 and not unit and v.is_integer():
        return str(int(v))
    return param_text(v, float32) + unit


def iso(t: float | None) -> str:
    """ISO-8601 UTC to the millisecond; a time the calendar cannot hold (a pcapng may state one before year 1
    or after 9999) as its number of seconds since 1970; "-" for none."""
    if t is None:
        return "-"
    try:
        dt = datetime.fromtimestamp(t, tz=timezone.utc)
    except (OverflowError, OSError, ValueError):
        return f"{t:.6g}s-since-1970-01-01T00:00:00Z"
    return dt.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def write_json(out: IO[bytes], doc: object) -> None:
    """One JSON document (NaN and infinities as null)."""
    out.write(orjson.dumps(doc, option=orjson.OPT_INDENT_2 | orjson.OPT_APPEND_NEWLINE | orjson.OPT_NON_STR_KEYS))
