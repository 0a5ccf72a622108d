"""The drawings' arithmetic, with values worked out by hand."""

from __future__ import annotations

import pytest

from mavscope.report.custody import key_names
from mavscope.report.geometry import (
    EARTH_M_PER_DEG,
    MAP_PAD,
    MAP_W,
    PLOT_PAD_L,
    PLOT_W,
    map_view,
    nice_step,
    plot_view,
)


@pytest.mark.parametrize(("span", "ticks", "step"), [(100, 4, 50), (7, 4, 2), (0.3, 3, 0.1), (1000, 1, 1000)])
def test_nice_step(span: float, ticks: int, step: float) -> None:
    # span / ticks rounded up to 1, 2 or 5 times a power of ten: 25 -> 50, 1.75 -> 2, 0.1 -> 0.1, 1000 -> 1000
    assert nice_step(span, ticks) == pytest.approx(step)


def test_the_envelope_keeps_each_columns_extremes() -> None:
    # 3 buckets: two start in the first pixel column (0 s and 0.001 s of 100 s), one at the end
    series = {"title": "t", "unit": "m", "count": 5, "divisor": 1000.0,
              "buckets": [[0.0, 1000, 2000], [0.001, -500, 1500], [100.0, 3000, 3000]]}
    v = plot_view(series, 100.0)
    assert (v.low, v.high) == (-0.5, 3.0)  # the first column: min(1, -0.5), max(2, 1.5); in metres
    top, bottom = v.upper.split(), v.lower.split()
    assert len(top) == len(bottom) == 2  # two columns, the first pixel's and the last one's
    assert float(top[0].split(",")[0]) == PLOT_PAD_L
    assert float(top[1].split(",")[0]) == PLOT_PAD_L + (PLOT_W - PLOT_PAD_L - 1)  # 100 s at the last column
    assert float(top[0].split(",")[1]) < float(bottom[0].split(",")[1])  # the max above the min (SVG y grows down)


def test_the_map_fits_and_measures() -> None:
    # two points 0.01 degrees of longitude apart on the equator: 1113.2 m, the wider extent
    geo = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[10.0, 0.0, 0], [10.01, 0.0, 0]]},
         "properties": {"kind": "track", "name": "system 1/1"}}]}
    v = map_view(geo)
    assert v is not None
    (track,) = v.shapes
    xs = [float(p.split(",")[0]) for p in track.points.split()]
    assert xs == pytest.approx([MAP_PAD, MAP_W - MAP_PAD], abs=0.1)  # fitted to the width
    metres_per_px = 0.01 * EARTH_M_PER_DEG / (MAP_W - 2 * MAP_PAD)
    # a quarter of the width is 200 px = 296 m: the bar is the round length below it, 200 m
    assert v.scale_px * metres_per_px == pytest.approx(200, rel=0.01)
    assert v.scale_text == "200 m"
    assert map_view({"type": "FeatureCollection", "features": []}) is None


def test_keys_are_named_never_shown() -> None:
    assert key_names(["vehicle=hex:" + "ab" * 32, "passphrase:secret=x", "file:ring.toml", "2=xor:hex:00"]) == [
        "vehicle", "(passphrase, unnamed)", "(file, unnamed)", "2"]
