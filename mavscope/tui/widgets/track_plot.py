"""A terminal plot of a mission: the vehicle's track as braille dots, the waypoints numbered, joined.

Braille cells give 2x4 dots per character; longitude is scaled by cos(latitude) so the plot keeps its
shape. Pure rendering in `plot_lines` (tested without Textual); the widget redraws on resize.
"""

from __future__ import annotations

import math

from rich.text import Text
from textual.widget import Widget

BRAILLE = 0x2800
DOTS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))  # [row][col] bit of a braille cell


def plot_lines(track: list[tuple[float, float]], waypoints: list[tuple[int, float, float]],
               width: int, height: int) -> Text:
    """Text of `width` x `height` cells: `track` (lat, lon) dots, `waypoints` (seq, lat, lon) joined."""
    pts = [(la, lo) for la, lo in track] + [(la, lo) for _, la, lo in waypoints]
    if not pts or width < 4 or height < 2:
        return Text("no positions in these frames", style="dim")
    lat0 = sum(p[0] for p in pts) / len(pts)
    k = max(0.01, math.cos(math.radians(lat0)))
    xs = [lo * k for _, lo in pts]
    ys = [la for la, _ in pts]
    xmin, xmax, ymin, ymax = min(xs), max(xs), min(ys), max(ys)
    # dots: 2 per cell across, 4 down; a cell is about twice as tall as wide, so a dot is square
    dw, dh = 2 * width, 4 * height
    scale = min((dw - 1) / max(xmax - xmin, 1e-9), (dh - 1) / max(ymax - ymin, 1e-9))
    cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2

    def dot(lat: float, lon: float) -> tuple[int, int]:
        x = int(round((lon * k - cx) * scale + (dw - 1) / 2))
        y = int(round((dh - 1) / 2 - (lat - cy) * scale))
        return max(0, min(dw - 1, x)), max(0, min(dh - 1, y))

    track_cells = [[0] * width for _ in range(height)]
    path_cells = [[0] * width for _ in range(height)]

    def put(cells: list[list[int]], x: int, y: int) -> None:
        cells[y // 4][x // 2] |= DOTS[y % 4][x % 2]

    for la, lo in track:
        put(track_cells, *dot(la, lo))
    prev = None
    for _, la, lo in waypoints:
        p = dot(la, lo)
        if prev is not None:
            n = max(abs(p[0] - prev[0]), abs(p[1] - prev[1]), 1)
            for i in range(n + 1):
                put(path_cells, prev[0] + (p[0] - prev[0]) * i // n, prev[1] + (p[1] - prev[1]) * i // n)
        prev = p
    labels: dict[tuple[int, int], str] = {}
    for seq, la, lo in waypoints:
        x, y = dot(la, lo)
        labels[(y // 4, x // 2)] = str(seq)[-1]
    out = Text(no_wrap=True, overflow="crop")
    for r in range(height):
        if r:
            out.append("\n")
        for c in range(width):
            if (r, c) in labels:
                out.append(labels[(r, c)], style="bold black on #ffaf00")
            elif path_cells[r][c]:
                out.append(chr(BRAILLE + (path_cells[r][c] | track_cells[r][c])), style="#ffaf00")
            elif track_cells[r][c]:
                out.append(chr(BRAILLE + track_cells[r][c]), style="#5fafff")
            else:
                out.append(" ")
    return out


class TrackPlot(Widget):
    """The plot; `set_data` gives it the track and the waypoints."""

    DEFAULT_CSS = """
    TrackPlot { height: 1fr; min-height: 8; }
    """

    def __init__(self, *, id: str | None = None) -> None:
        super().__init__(id=id)
        self.track: list[tuple[float, float]] = []
        self.waypoints: list[tuple[int, float, float]] = []

    def set_data(self, track: list[tuple[float, float]], waypoints: list[tuple[int, float, float]]) -> None:
        self.track, self.waypoints = track, waypoints
        self.refresh()

    def render(self) -> Text:
        size = self.content_size
        return plot_lines(self.track, self.waypoints, size.width, size.height)
