"""The coordinates of the page's drawings: the map (the report's GeoJSON, projected) and the plots (the
series' buckets folded into one column per pixel, each column's minimum and maximum kept: the envelope).

Only numbers leave this module (point lists as text of numbers); every word the drawings show goes
through the template, which escapes it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

MAP_W, MAP_H, MAP_PAD = 800.0, 520.0, 24.0
PLOT_W, PLOT_H, PLOT_PAD_L, PLOT_PAD_B = 800.0, 160.0, 56.0, 22.0
MAX_MAP_POINTS = 4000  # points drawn of one line (the JSON keeps every one)
MAX_MAP_TRACKS = 20  # tracks drawn: those of the most positions (the JSON keeps every one)
MAX_MAP_SHAPES = 2000  # waypoints, fence polygons and circles, rally points drawn, of each kind
EARTH_M_PER_DEG = 111_320.0  # metres per degree of latitude (and of longitude at the equator)
NICE = (1, 2, 5)
FEW_COLUMNS = 60  # a plot of at most this many pixel columns with values draws a dot at each


def nice_step(span: float, ticks: int = 4) -> float:
    """A round step (1, 2 or 5 times a power of ten) that divides `span` in about `ticks` parts."""
    if not span > 0 or not math.isfinite(span):
        return 1.0
    raw = span / ticks
    power = 10 ** math.floor(math.log10(raw))
    return next((n * power for n in NICE if n * power >= raw), 10 * power)


def nice_floor(x: float) -> float:
    """The largest round length (1, 2 or 5 times a power of ten) not above `x` (> 0)."""
    if not x > 0 or not math.isfinite(x):
        return 1.0
    power = 10 ** math.floor(math.log10(x))
    return max(n * power for n in NICE if n * power <= x * (1 + 1e-12))


def _fmt(v: float) -> str:
    return f"{v:.1f}".rstrip("0").rstrip(".") if math.isfinite(v) else "0"


@dataclass
class Shape:
    kind: str  # track, mission, waypoint, home, fence, fence-circle, rally
    name: str
    points: str = ""  # "x,y x,y ..." for lines and polygons
    x: float = 0.0
    y: float = 0.0
    r: float = 0.0  # a fence circle's radius in pixels
    colour: int = 0  # the track's number, for its colour
    inclusion: bool = True


@dataclass
class MapView:
    shapes: list[Shape] = field(default_factory=list)
    scale_px: float = 0.0  # the scale bar's length in pixels...
    scale_text: str = ""  # ...and what it measures
    width: float = MAP_W
    height: float = MAP_H
    left_out: dict[str, int] = field(default_factory=dict)  # kind -> features not drawn (MAX_MAP_TRACKS, _SHAPES)


def _coords(geom: dict) -> list[Sequence[float]]:
    kind, c = geom.get("type"), geom.get("coordinates")
    if not isinstance(c, list):
        return []
    if kind == "Point":
        return [c]
    if kind == "LineString":
        return list(c)
    if kind == "Polygon":
        return list(c[0]) if c and isinstance(c[0], list) else []
    return []


def _ok(p: Sequence[float]) -> bool:
    return len(p) >= 2 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in p[:2]) \
        and -180 <= p[0] <= 180 and -90 <= p[1] <= 90


def _drawn(feats: list[dict]) -> tuple[list[dict], dict[str, int]]:
    """The features drawn, in their order (the tracks of the most positions, MAX_MAP_TRACKS of them; of each
    other kind the first MAX_MAP_SHAPES), and how many of each kind are not."""
    def kind(f: dict) -> str:
        return str((f.get("properties") or {}).get("kind", ""))

    def positions(f: dict) -> int:
        n = (f.get("properties") or {}).get("positions")
        return n if isinstance(n, int) else 0

    tracks = [f for f in feats if kind(f) == "track"]
    keep = {id(f) for f in sorted(tracks, key=lambda f: -positions(f))[:MAX_MAP_TRACKS]}
    seen: dict[str, int] = {}
    out: list[dict] = []
    left_out: dict[str, int] = {}
    for f in feats:
        k = kind(f)
        seen[k] = seen.get(k, 0) + 1
        if (id(f) in keep) if k == "track" else seen[k] <= MAX_MAP_SHAPES:
            out.append(f)
        else:
            left_out[k] = left_out.get(k, 0) + 1
    return out, left_out


def map_view(geo: dict) -> MapView | None:
    """The features of `geo` (a GeoJSON FeatureCollection) on an equirectangular projection about their
    middle latitude, north up, fitted into the drawing; None when nothing has a position."""
    feats, left_out = _drawn([f for f in geo.get("features", []) if isinstance(f, dict)])
    pts = [p for f in feats for p in _coords(f.get("geometry") or {}) if _ok(p)]
    if not pts:
        return None
    lons, lats = [p[0] for p in pts], [p[1] for p in pts]
    lat0 = (min(lats) + max(lats)) / 2
    k = max(math.cos(math.radians(lat0)), 1e-6)
    span_x = max((max(lons) - min(lons)) * k, 1e-7)
    span_y = max(max(lats) - min(lats), 1e-7)
    scale = min((MAP_W - 2 * MAP_PAD) / span_x, (MAP_H - 2 * MAP_PAD) / span_y)  # px per degree of latitude
    cx, cy = (min(lons) + max(lons)) / 2, lat0

    def xy(p: Sequence[float]) -> tuple[float, float]:
        return MAP_W / 2 + (p[0] - cx) * k * scale, MAP_H / 2 - (p[1] - cy) * scale

    def line(ps: list[Sequence[float]]) -> str:
        ps = [p for p in ps if _ok(p)]
        step = max(1, math.ceil(len(ps) / MAX_MAP_POINTS))
        kept = ps[::step] + ([ps[-1]] if ps and (len(ps) - 1) % step else [])
        return " ".join(f"{x:.1f},{y:.1f}" for x, y in map(xy, kept))

    view = MapView(left_out=left_out)
    tracks = 0
    for f in feats:
        props, geom = f.get("properties") or {}, f.get("geometry") or {}
        kind, name = str(props.get("kind", "")), str(props.get("name", ""))
        cs = [p for p in _coords(geom) if _ok(p)]
        if not cs:
            continue
        inclusion = bool(props.get("inclusion", True))
        if geom.get("type") in ("LineString", "Polygon"):
            view.shapes.append(Shape(kind, name, line(cs), colour=tracks, inclusion=inclusion))
            tracks += kind == "track"
            continue
        x, y = xy(cs[0])
        radius = props.get("radius_m")
        r = float(radius) / EARTH_M_PER_DEG * scale if isinstance(radius, (int, float)) and math.isfinite(radius) \
            and radius > 0 else 0.0
        view.shapes.append(Shape(kind, name, x=round(x, 1), y=round(y, 1), r=round(min(r, 4 * MAP_W), 1),
                                 colour=tracks, inclusion=inclusion))
    metres_per_px = EARTH_M_PER_DEG / scale
    bar = nice_floor(metres_per_px * MAP_W / 4)  # a round length of at most a quarter of the width
    view.scale_px = round(bar / metres_per_px, 1)
    view.scale_text = f"{_fmt(bar / 1000)} km" if bar >= 1000 else f"{_fmt(bar)} m"
    return view


@dataclass
class PlotView:
    title: str
    unit: str
    envelope: str = ""  # polygon: the maxima left to right, then the minima right to left
    upper: str = ""
    lower: str = ""
    y_ticks: list[tuple[float, str]] = field(default_factory=list)
    x_ticks: list[tuple[float, str]] = field(default_factory=list)
    count: int = 0
    low: float | None = None
    high: float | None = None
    lines: list[tuple[str, str]] = field(default_factory=list)  # (name, polyline): the signing plot's
    marks: list[tuple[float, str]] = field(default_factory=list)  # (x, what): link losses and recoveries
    dots: list[tuple[float, float]] = field(default_factory=list)  # each column's maximum, when columns are few


def _x_ticks(x_end: float) -> list[tuple[float, str]]:
    step = nice_step(x_end, 5)
    width = PLOT_W - PLOT_PAD_L
    return [(round(PLOT_PAD_L + v / x_end * width, 1), f"{_fmt(v)} s")
            for v in (i * step for i in range(int(x_end / step) + 1))] if x_end > 0 else []


def _columns(buckets: Sequence[Sequence[float]], x_end: float, divisor: float) -> list[tuple[float, float, float]]:
    """Per pixel column (x in pixels), the minimum and maximum of the buckets starting in it."""
    width = PLOT_W - PLOT_PAD_L
    cols: dict[int, tuple[float, float]] = {}
    for start, low, high in buckets:
        if not (math.isfinite(low) and math.isfinite(high)):
            continue
        px = int(start / x_end * (width - 1)) if x_end > 0 else 0
        lo, hi = low / divisor, high / divisor
        old = cols.get(px)
        cols[px] = (lo, hi) if old is None else (min(old[0], lo), max(old[1], hi))
    return [(PLOT_PAD_L + px, lo, hi) for px, (lo, hi) in sorted(cols.items())]


def _y_scale(low: float, high: float) -> tuple[float, float, list[tuple[float, str]]]:
    if high - low < 1e-9:
        low, high = low - 1, high + 1
    step = nice_step(high - low, 3)
    y0, y1 = math.floor(low / step) * step, math.ceil(high / step) * step
    ticks = [(round(PLOT_H - PLOT_PAD_B - (v - y0) / (y1 - y0) * (PLOT_H - PLOT_PAD_B - 6), 1), _fmt(v))
             for v in (y0 + i * step for i in range(int(round((y1 - y0) / step)) + 1))]
    return y0, y1, ticks


def _y(v: float, y0: float, y1: float) -> float:
    return round(PLOT_H - PLOT_PAD_B - (v - y0) / (y1 - y0) * (PLOT_H - PLOT_PAD_B - 6), 1)


def plot_view(series: dict, x_end: float) -> PlotView:
    """The envelope of one plotted field (the report's `plots` entry) over [0, x_end] seconds."""
    view = PlotView(str(series["title"]), str(series["unit"]), count=int(series["count"]))
    cols = _columns(series["buckets"], x_end, float(series["divisor"]) or 1.0)
    if not cols:
        return view
    view.low, view.high = min(c[1] for c in cols), max(c[2] for c in cols)
    y0, y1, view.y_ticks = _y_scale(view.low, view.high)
    top = [f"{x:.1f},{_y(hi, y0, y1)}" for x, _, hi in cols]
    bottom = [f"{x:.1f},{_y(lo, y0, y1)}" for x, lo, _ in cols]
    view.upper, view.lower = " ".join(top), " ".join(bottom)
    view.envelope = " ".join(top + bottom[::-1])
    if len(cols) <= FEW_COLUMNS:  # a value or two would be no line at all: each is drawn as a dot too
        view.dots = [(x, _y(hi, y0, y1)) for x, _, hi in cols] + [(x, _y(lo, y0, y1)) for x, lo, hi in cols if lo != hi]
    view.x_ticks = _x_ticks(x_end)
    return view


def signing_view(doc: dict, x_end: float, origin: float | None, marks: Sequence[tuple[float, str]]) -> PlotView:
    """Frames per second of each signature verdict (the report's `signing_over_time`), with the link losses
    and recoveries (`marks`: capture time, what) as marks on the same time axis."""
    view = PlotView("Signature verdicts and link losses", "frames/s")
    per: dict[str, list[list[float]]] = doc.get("verdicts") or {}
    values = [v for pts in per.values() for _, v in pts]
    if not values:
        return view
    view.count = len(values)
    view.low, view.high = 0.0, max(values)
    y0, y1, view.y_ticks = _y_scale(0.0, view.high)
    for name in sorted(per):
        buckets = [(s, v, v) for s, v in per[name]]
        cols = _columns(buckets, x_end, 1.0)
        view.lines.append((name, " ".join(f"{x:.1f},{_y(hi, y0, y1)}" for x, _, hi in cols)))
    view.x_ticks = _x_ticks(x_end)
    width = PLOT_W - PLOT_PAD_L
    if origin is not None and x_end > 0:
        view.marks = [(round(PLOT_PAD_L + min(max((t - origin) / x_end, 0.0), 1.0) * (width - 1), 1), what)
                      for t, what in marks if math.isfinite(t)]
    return view
