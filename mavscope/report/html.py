"""The report document as one self-contained HTML page (Jinja2 with autoescape on: every string of the
document, which may come from a capture or a dialect, is escaped by the template engine; no string of the
document reaches the page's only script, which opens the folded tables for printing).

Long lists are cut at a number of rows, with a line saying how many more and the command that lists them
all; long tables are folded (<details>). Nothing is loaded from anywhere: CSS, SVG and the script are in
the page, and no URL is written into it.
"""

from __future__ import annotations

import math
import shlex

import jinja2

from mavscope.output.tables import iso
from mavscope.report.geometry import (
    MAP_H,
    MAP_W,
    PLOT_H,
    PLOT_PAD_B,
    PLOT_PAD_L,
    PLOT_W,
    map_view,
    plot_view,
    signing_view,
)
from mavscope.report.template import TEMPLATE, VERDICT_COLOURS

ROWS = {"events": 400, "params": 300, "files": 300, "links": 200, "messages": 150, "commanders": 100,
        "frames": 12, "items": 200, "transfers": 200, "uploads": 5, "key": 30,
        "systems": 100, "findings": 200, "summary_findings": 40}
KEY_KINDS = ("vehicle", "arming", "mode", "failsafe", "reboot", "signing")  # the summary's key events
FOLD_OVER = 25  # a table of more rows than this is folded


def _size(n: object) -> str:
    if not isinstance(n, int):
        return "-"
    if n < 1024:
        return f"{n:,} bytes"
    x = float(n)
    for unit in ("KiB", "MiB", "GiB"):
        x /= 1024
        if x < 1024 or unit == "GiB":
            break
    return f"{x:,.1f} {unit}"


def _duration(s: object) -> str:
    if not isinstance(s, (int, float)) or not math.isfinite(s):
        return "-"
    s = float(s)
    if s < 120:
        return f"{s:.1f} s"
    m, sec = divmod(int(s), 60)
    h, m = divmod(m, 60)
    return f"{h} h {m:02d} min {sec:02d} s" if h else f"{m} min {sec:02d} s"


def _addr(a: object) -> str:
    return f"{a[0]}/{a[1]}" if isinstance(a, list) and len(a) == 2 else "-"


def _counts(d: object) -> str:
    return ", ".join(f"{k} {v:,}" for k, v in d.items()) if isinstance(d, dict) and d else "-"


def _marks(events: list[dict]) -> list[tuple[float, str]]:
    out = []
    for e in events:
        d = e.get("details") or {}
        if e.get("kind") == "link" and isinstance(e.get("time"), (int, float)):
            out.append((float(e["time"]), f"{_addr(e['from'])} {d.get('what', '')}"))
    return out


def _view(doc: dict) -> dict:
    """What the template draws for one input, beside its document."""
    span = doc["span"]
    x_end = float(span["duration"] or 0.0)
    plots = [plot_view(s, x_end) for s in doc["plots"]]
    events = doc["events"]["events"]
    signing = signing_view(doc["signing_over_time"], x_end, doc["signing_over_time"].get("start"), _marks(events))
    path = doc["file"]["path"]
    q = shlex.quote(path)
    return {"map": map_view(doc["map"]), "plots": plots, "signing": signing,
            "more": {"events": f"mavscope events {q} --json", "params": f"mavscope params {q} --json",
                     "files": f"mavscope objects {q} --json", "links": f"mavscope stats {q} --json",
                     "findings": f"mavscope audit {q} --json", "missions": f"mavscope mission {q} --json"}}


def environment() -> jinja2.Environment:
    env = jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
                             lstrip_blocks=True, keep_trailing_newline=True)
    env.filters.update(iso=iso, size=_size, duration=_duration, addr=_addr, counts=_counts)
    return env


def render(doc: dict) -> str:
    """The page of the report document `doc` (model.document)."""
    template = environment().from_string(TEMPLATE)
    return template.render(doc=doc, views=[_view(i) for i in doc["inputs"]], rows=ROWS, fold=FOLD_OVER,
                           colours=VERDICT_COLOURS, key_kinds=KEY_KINDS, map_w=MAP_W, map_h=MAP_H, plot_w=PLOT_W,
                           plot_h=PLOT_H, pad_l=PLOT_PAD_L, pad_b=PLOT_PAD_B)
