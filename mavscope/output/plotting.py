"""A series drawn in the terminal with braille dots (2 x 4 per character cell), as rich Text: per dot column
the range from the lowest to the highest value of the buckets it covers (joined to the previous column),
so a spike shows however many buckets share a column. Used by `mavscope plot` and the TUI's plot screen;
`image()` draws the same series with matplotlib (an optional extra) to PNG or SVG.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import BinaryIO

from rich.text import Text

from mavscope.analysis.series import Series
from mavscope.errors import UsageError
from mavscope.output.console import visible

BRAILLE = 0x2800
DOTS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))  # [row][col] bit of a braille cell


def _num(v: float) -> str:
    """A computed number (a mean, an interval, an axis label) to 6 significant digits."""
    return f"{v:.6g}"


def _value(v: float) -> str:
    """A value of the field (the minimum, the maximum) as the shortest text that reads back as it: a float32
    field's values are the doubles of their shortest decimals (analysis/series.py), so repr writes 30.48; an
    integer field's whole numbers as integers (473977419, not 4.73977e+08)."""
    return str(int(v)) if v.is_integer() and abs(v) < 2**53 and repr(v) != "-0.0" else repr(v)


def summary(s: Series, x_label: str) -> str:
    """"FIELD [units]: N values, min .. max, mean M; interval W unit"."""
    units = f" [{s.units}]" if s.units else ""
    skipped = f" ({s.not_finite} NaN or infinite left out)" if s.not_finite else ""
    if not s.count:
        return f"{s.name}{units}: no values{skipped}"
    return (f"{s.name}{units}: {s.count} values{skipped}, min {_value(s.low)}, max {_value(s.high)}, "
            f"mean {_num(s.total / s.count)}; interval {_num(s.width)} {x_label}")


def chart(s: Series, width: int, height: int, x_label: str = "s") -> Text:
    """The series in `width` x `height` character cells (y labels included), under its summary line."""
    out = Text(visible(summary(s, x_label)) + "\n", style="bold")  # a field name the user gave
    if not s.count:
        return out
    pad = max(1.0, abs(s.low) * 2 ** -40)  # a constant: one unit either side, or enough to be a different float
    lo, hi = (s.low, s.high) if s.high > s.low else (s.low - pad, s.high + pad)
    h2, l2 = hi / 2, lo / 2  # halves: the span of -1e308 .. 1e308 overflows, its half does not
    span = h2 - l2
    rows = max(2, height)
    labels = {0: _num(hi), rows - 1: _num(lo), rows // 2: _num(h2 + l2)}
    gutter = max(len(v) for v in labels.values()) + 2
    cols = max(4, width - gutter)
    dw, dh = 2 * cols, 4 * rows
    n = len(s.buckets)
    cells = [[0] * cols for _ in range(rows)]

    def row_of(v: float) -> int:
        r = (h2 - v / 2) / span * (dh - 1)  # a mean of huge values can be infinite: an edge of the chart
        return max(0, min(dh - 1, int(round(r)))) if math.isfinite(r) else (dh - 1 if r > 0 else 0)

    def put(x: int, low: float, high: float) -> None:
        for y in range(row_of(high), row_of(low) + 1):
            cells[y // 4][x // 2] |= DOTS[y % 4][x % 2]

    prev: tuple[int, float] | None = None
    for x in range(dw):
        first, last = x * n // dw, max(x * n // dw + 1, (x + 1) * n // dw)
        low, high, total, count = math.inf, -math.inf, 0.0, 0
        for b in s.buckets[first:last]:
            if b is not None:
                low, high, total, count = min(low, b.low), max(high, b.high), total + b.total, count + b.count
        if not count:
            continue
        avg = total / count
        if prev is not None:  # a line from the previous column with values, through any empty ones
            px, pv = prev
            for gx in range(px + 1, x):
                t = (gx - px) / (x - px)
                v = pv * (1 - t) + avg * t  # not pv + (avg - pv) * t: avg - pv can overflow
                put(gx, v, v)
            t = (x - 1 - px) / (x - px)
            joint = pv * (1 - t) + avg * t
            low, high = min(low, joint), max(high, joint)
        put(x, low, high)
        prev = (x, avg)
    for r in range(rows):
        out.append(f"{labels.get(r, ''):>{gutter - 2}} ┤", style="dim")
        out.append("".join(chr(BRAILLE + c) if c else " " for c in cells[r]), style="cyan")
        out.append("\n")
    end = n * s.width
    axis = f"0 {x_label}".ljust(cols - len(_num(end)) - len(x_label) - 1) + f"{_num(end)} {x_label}"
    out.append(" " * gutter + axis[:cols], style="dim")
    return out


def image(series: Sequence[Series], x_label: str, path: str, title: str, file: BinaryIO | None = None) -> None:
    """The series (one panel each: the mean as a line, minimum to maximum shaded) written to `path`, a
    .png or .svg, with matplotlib (or, as PNG, to `file`: standard output for `--out -`). UsageError when
    matplotlib is missing or the file cannot be written."""
    fmt = "png" if file is not None else path.rsplit(".", 1)[-1].lower() if "." in path else ""
    if fmt not in ("png", "svg"):
        raise UsageError(f"plot: --out {path}: the file name must end in .png or .svg")
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsageError("plot: --out needs matplotlib, which is not installed (pip install 'mavscope[plot]')") \
            from None
    fig, axes = plt.subplots(len(series), 1, sharex=True, squeeze=False, figsize=(10, 2.6 * len(series) + 0.6))
    for ax, s in zip(axes[:, 0], series):
        xs = [i * s.width for i, b in enumerate(s.buckets) if b is not None]
        bs = [b for b in s.buckets if b is not None]
        ax.fill_between(xs, [b.low for b in bs], [b.high for b in bs], step="post", alpha=0.3, label="min .. max")
        ax.step(xs, [b.total / b.count for b in bs], where="post", linewidth=1.0, label="mean")
        ax.set_ylabel(f"{s.name}" + (f" [{s.units}]" if s.units else ""), fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    axes[-1, 0].set_xlabel(f"{x_label} (interval {_num(series[0].width)} {x_label})" if series else x_label)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    try:
        fig.savefig(path if file is None else file, format=fmt,
                    metadata={"Software": None} if fmt == "png" else {"Date": None})
    except OSError as exc:
        raise UsageError(f"plot: --out {path}: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)
