"""The report in a real browser: Debian's headless Chromium (scripts/install-test-tools.sh installs it; the
tests skip with that reason without it) loads the page from disk. The DOM it renders has every section, the
capture's SHA-256 (computed here with hashlib), as many event rows as the JSON lists; the load makes no
request but the page itself and no console error; screenshots at a narrow and a wide width are real
images (not blank, as wide as asked). `test_the_rendered_page` is the fast tier's cheap one; the rest load
the page under the DevTools protocol or take screenshots (slow tier, tests/support/tiers.py)."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import pytest

from tests.conftest import CAPTURES, Cli
from tests.support import browser
from tests.support import report_flight as fl

pytestmark = browser.SKIP
SECTIONS = ("custody", "summary-1", "findings-1", "timeline-1", "map-1", "plots-1", "missions-1", "params-1",
            "files-1", "links-1")


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, Path]:
    tmp = tmp_path_factory.mktemp("browser")
    cap, _ = fl.write(tmp)
    status, _, err = Cli()("report", str(cap), str(CAPTURES / "gps_spoof.pcap"), "-o", str(tmp / "r.html"),
                           "--json", str(tmp / "r.json"))
    assert status == 0, err
    return tmp / "r.html", json.loads((tmp / "r.json").read_text()), cap


def test_the_rendered_page(report: tuple[Path, dict, Path]) -> None:
    page, doc, cap = report
    dom = browser.dump_dom(page)
    for s in (*SECTIONS, "summary-2", "map-2"):
        assert f'id="{s}"' in dom, s
    assert hashlib.sha256(cap.read_bytes()).hexdigest() in dom
    assert hashlib.sha256((CAPTURES / "gps_spoof.pcap").read_bytes()).hexdigest() in dom
    for n, one in enumerate(doc["inputs"], 1):
        table = re.search(rf'<table class="wide" id="events-{n}">(.*?)</table>', dom, re.S)
        assert table is not None
        assert table.group(1).count("<tr class=\"ev-") == len(one["events"]["events"])
    assert dom.count('class="finding"') == sum(len(i["findings"]) for i in doc["inputs"])
    assert "<svg" in dom and 'id="mapsvg-2"' in dom  # gps_spoof.pcap's track is drawn
    mine = re.search(r'<svg[^>]*id="mapsvg-1">(.*?)</svg>', dom, re.S)
    assert mine is not None  # the built flight's map: its fence, rally point, home and waypoint
    for title in ("fence inclusion", "rally 1", "home", "1 NAV_WAYPOINT", "system 1/1 (GLOBAL_POSITION_INT)"):
        assert f"<title>{title}</title>" in mine.group(1), title


def test_nothing_is_fetched_and_nothing_fails(report: tuple[Path, dict, Path]) -> None:
    page, doc, _ = report
    got = browser.load(page, ("document.querySelectorAll('section').length",
                              "document.querySelectorAll('tr.ev-statustext').length",
                              "[...document.querySelectorAll('[src],[href]')].map(e => e.getAttribute('src') || "
                              "e.getAttribute('href')).filter(u => !u.startsWith('#')).length",
                              "document.querySelector('.sha256').textContent"))
    assert got.requests == [page.as_uri()]  # the page itself, nothing else
    assert got.errors() == []
    values = list(got.values.values())
    assert values[0] == 1 + 9 * len(doc["inputs"])  # custody, then nine sections per capture
    assert values[1] == sum(1 for i in doc["inputs"] for e in i["events"]["events"] if e["kind"] == "statustext")
    assert values[2] == 0
    assert values[3] == doc["inputs"][0]["file"]["sha256"]


def test_the_watch_sees_a_request(tmp_path: Path) -> None:
    """The network check can fail: a page that asks for an image is seen asking (nothing leaves the machine:
    the browser has no network)."""
    page = tmp_path / "p.html"
    page.write_text('<!DOCTYPE html><html><body><img src="http://mavscope.invalid/x.png">'
                    "<script>console.error('boom')</script></body></html>")
    got = browser.load(page)
    assert "http://mavscope.invalid/x.png" in got.requests
    assert got.errors()


@pytest.mark.parametrize("width", [420, 1400])
def test_screenshots(report: tuple[Path, dict, Path], tmp_path: Path, width: int) -> None:
    """At a phone's width and a desktop's: the page is no wider than the window (wide tables and plots scroll
    in their own boxes), and the picture has text, tables and cards on it (not blank)."""
    from PIL import Image

    page, _, _ = report
    png = tmp_path / f"r{width}.png"
    got = browser.load(page, ("document.documentElement.scrollWidth",), width=width, height=2400, shot=png)
    assert got.values["document.documentElement.scrollWidth"] <= width
    with Image.open(png) as im:
        assert im.size == (width, 2400)
        grey = im.convert("L")
        colours = grey.getcolors(maxcolors=1 << 16)
        assert colours is not None and len(colours) > 8
        right = [grey.getpixel((width - 1, y)) for y in range(0, 2400, 8)]  # the rightmost column: background
        assert min(right) > 200  # type: ignore[operator]
