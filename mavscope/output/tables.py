"""Presentation helpers for the analysis commands: a rich Console on the command's stdout, sparklines,
number formats, and the JSON writer. The analysis core (mavscope.analysis) never imports this."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime, timezone

import orjson

from mavscope.cli import Env

BARS = "▁▂▃▄▅▆▇█"


def console(env: Env):  # type: ignore[no-untyped-def]
    """A rich Console writing to env.stdout: colour only on a terminal, wide tables when piped."""
    from rich.console import Console

    try:
        tty = env.stdout.isatty()
    except (AttributeError, ValueError):
        tty = False
    if tty:
        return Console(file=env.stdout)
    width = env.environ.get("COLUMNS", "")
    return Console(file=env.stdout, no_color=True, color_system=None, highlight=False, emoji=False,
                   width=int(width) if width.isdigit() else 160)


def sparkline(values: Sequence[int | float], width: int = 40) -> str:
    """Values as a row of block characters (averaged into at most `width` buckets)."""
    if not values:
        return ""
    if len(values) > width:
        step = len(values) / width
        values = [sum(values[int(i * step): max(int((i + 1) * step), int(i * step) + 1)]) /
                  max(1, int((i + 1) * step) - int(i * step)) for i in range(width)]
    top = max(values)
    if top <= 0:
        return BARS[0] * len(values)
    return "".join(BARS[min(len(BARS) - 1, int(v / top * (len(BARS) - 1) + 0.5))] for v in values)


def fmt(value: object, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}"
    return str(value)


def iso(t: float | None) -> str:
    if t is None:
        return "-"
    return datetime.fromtimestamp(t, tz=timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def write_json(env: Env, doc: object) -> None:
    """One JSON document on stdout (NaN and infinities as null)."""
    out = env.stdout_bytes
    out.write(orjson.dumps(doc, option=orjson.OPT_INDENT_2 | orjson.OPT_APPEND_NEWLINE | orjson.OPT_NON_STR_KEYS))
    out.flush()
