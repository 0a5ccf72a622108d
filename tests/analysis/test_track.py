"""`mavscope track`: tracks and mission, fence and rally points as GeoJSON, KML and GPX. Positions are
checked against pymavlink's reading of the same capture; every output is parsed back (json for GeoJSON,
xml.etree for KML and GPX) and its structure checked against its specification (RFC 7946, KML 2.2 with
the gx:Track extension, GPX 1.1)."""

from __future__ import annotations

import json
import math
from datetime import datetime
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from mavscope.analysis import track as track_mod
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.output.geo import xsd_time
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.analysis.mission_exchange import Exchange
from tests.conftest import CAPTURES, Cli
from tests.support.pymavlink_reader import read_pcap

GPX = "{http://www.topografix.com/GPX/1/1}"
KML = "{http://www.opengis.net/kml/2.2}"
GX = "{http://www.google.com/kml/ext/2.2}"
TAKEOVER = CAPTURES / "gcs_takeover.pcap"


def _iso(text: str) -> float:
    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


@pytest.fixture(scope="module")
def positions() -> list[tuple[float, float, float, float]]:
    """(time, lat, lon, alt m) of every GLOBAL_POSITION_INT of gcs_takeover.pcap, read by pymavlink."""
    return [(m.time, m.msg.lat / 1e7, m.msg.lon / 1e7, m.msg.alt / 1000) for m in read_pcap(TAKEOVER)
            if m.name == "GLOBAL_POSITION_INT"]


def _ring_area(ring: list[list[float]]) -> float:
    return sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(ring, ring[1:])) / 2


def test_geojson_track_and_mission(tmp_path: Path, cli: Cli, positions: list) -> None:  # type: ignore[type-arg]
    out = tmp_path / "t.geojson"
    status, _, err = cli("track", TAKEOVER, "--geojson", out)
    assert status == 0, err
    doc = json.loads(out.read_text(encoding="utf-8"))
    assert doc["type"] == "FeatureCollection" and "crs" not in doc  # RFC 7946 section 4: no crs member
    for f in doc["features"]:
        assert f["type"] == "Feature" and set(f) == {"type", "geometry", "properties"}
        assert f["geometry"]["type"] in ("Point", "LineString", "Polygon")
    (trk,) = [f for f in doc["features"] if f["properties"]["kind"] == "track"]
    coords, times = trk["geometry"]["coordinates"], trk["properties"]["times"]
    assert len(coords) == len(times) == len(positions) == 300  # the generator's 5 Hz for 60 s
    for (lon, lat, alt), when, (t, plat, plon, palt) in zip(coords, times, positions):
        assert (lon, lat) == (plon, plat)  # longitude first (RFC 7946 section 3.1.1)
        assert alt == pytest.approx(palt) and _iso(when) == pytest.approx(t, abs=0.0015)
    (mission,) = [f for f in doc["features"] if f["properties"]["kind"] == "mission"]
    wps = [f for f in doc["features"] if f["properties"]["kind"] == "waypoint"]
    # the generator's mission: takeoff at home, waypoints 60 m north, then 60 m east of that, then RTL
    assert [w["properties"]["command"] for w in wps] == ["NAV_TAKEOFF", "NAV_WAYPOINT", "NAV_WAYPOINT"]
    assert mission["geometry"]["coordinates"] == [w["geometry"]["coordinates"] for w in wps]
    assert mission["geometry"]["coordinates"][0][:2] == [8.5455938, 47.3977419]
    # the takeover GCS's MISSION_CLEAR_ALL, accepted by the vehicle's MISSION_ACK (pymavlink's reading):
    # the vehicle holds no mission since that ACK, so the mission is drawn as its history, until then
    msgs = read_pcap(TAKEOVER)
    clear = next(i for i, m in enumerate(msgs) if m.name == "MISSION_CLEAR_ALL")
    ack = next(m for m in msgs[clear:] if m.name == "MISSION_ACK" and m.src[0] == 1 and m.msg.type == 0)
    assert {(f["properties"]["state"], f["properties"]["until"]) for f in [mission, *wps]} == {
        ("history", xsd_time(ack.time))}


def test_kml_and_gpx_parse_back(tmp_path: Path, cli: Cli, positions: list) -> None:  # type: ignore[type-arg]
    kml, gpx = tmp_path / "t.kml", tmp_path / "t.gpx"
    status, _, err = cli("track", TAKEOVER, "--kml", kml, "--gpx", gpx)
    assert status == 0, err
    root = ET.parse(kml).getroot()
    assert root.tag == f"{KML}kml"
    (gxtrack,) = root.iter(f"{GX}Track")
    whens = [w.text for w in gxtrack.iter(f"{KML}when")]
    coords = [c.text.split() for c in gxtrack.iter(f"{GX}coord")]  # type: ignore[union-attr]
    assert len(whens) == len(coords) == len(positions)
    assert [float(c[0]) for c in coords[:5]] == pytest.approx([p[2] for p in positions[:5]], abs=1e-7)
    assert [float(c[1]) for c in coords[:5]] == pytest.approx([p[1] for p in positions[:5]], abs=1e-7)
    root = ET.parse(gpx).getroot()
    assert root.tag == f"{GPX}gpx" and root.get("version") == "1.1" and root.get("creator")
    order = [child.tag.removeprefix(GPX) for child in root]
    assert order == sorted(order, key=["wpt", "rte", "trk"].index)  # GPX 1.1: wpt*, rte*, trk*
    (trk,) = root.findall(f"{GPX}trk")
    pts = trk.findall(f"{GPX}trkseg/{GPX}trkpt")
    assert len(pts) == len(positions)
    for pt, (t, lat, lon, alt) in zip(pts[:20], positions[:20]):
        assert (float(pt.get("lat")), float(pt.get("lon"))) == pytest.approx((lat, lon), abs=1e-7)  # type: ignore[arg-type]
        assert [c.tag.removeprefix(GPX) for c in pt] == ["ele", "time"]
        assert _iso(pt.findtext(f"{GPX}time")) == pytest.approx(t, abs=0.0015)  # type: ignore[arg-type]
    (rte,) = root.findall(f"{GPX}rte")
    assert len(rte.findall(f"{GPX}rtept")) == 3 and rte.findtext(f"{GPX}name").startswith("mission (history")  # type: ignore[union-attr]


def _fence_and_rally(tmp_path: Path) -> str:
    """An upload of an inclusion polygon (4 vertices, clockwise as drawn), an exclusion circle and two
    rally points, each transfer accepted, plus a short track of the vehicle."""
    ex = Exchange()
    ex.heartbeats(vehicle_type=2, autopilot=3)
    square = [(47.0, 8.0), (47.0, 8.01), (46.99, 8.01), (46.99, 8.0)]  # clockwise seen from above
    ex.send("gcs", "MISSION_COUNT", 1, 1, 5, 1)
    for seq, (lat, lon) in enumerate(square):
        ex.send("veh", "MISSION_REQUEST_INT", 255, 190, seq, 1)
        ex.send("gcs", "MISSION_ITEM_INT", 1, 1, seq, 0, 5001, 0, 1, 4, 0, 0, 0, round(lat * 1e7), round(lon * 1e7),
                0, 1)
    ex.send("veh", "MISSION_REQUEST_INT", 255, 190, 4, 1)
    ex.send("gcs", "MISSION_ITEM_INT", 1, 1, 4, 0, 5004, 0, 1, 50.0, 0, 0, 0, 469950000, 80050000, 0, 1)
    ex.send("veh", "MISSION_ACK", 255, 190, 0, 1)
    ex.send("gcs", "MISSION_COUNT", 1, 1, 2, 2)
    for seq in range(2):
        ex.send("veh", "MISSION_REQUEST_INT", 255, 190, seq, 2)
        ex.send("gcs", "MISSION_ITEM_INT", 1, 1, seq, 0, 5100, 0, 1, 0, 0, 0, 0, 469960000 + seq * 1000, 80020000,
                30.0, 2)
    ex.send("veh", "MISSION_ACK", 255, 190, 0, 2)
    for i in range(3):
        ex.send("veh", "GLOBAL_POSITION_INT", 1000 + i * 200, 469970000 + i * 10, 80030000, 500_000, 20_000, 0, 0, 0, 0)
    return ex.tlog(tmp_path / "fence.tlog")


def test_fence_and_rally_in_every_format(tmp_path: Path, cli: Cli) -> None:
    path = _fence_and_rally(tmp_path)
    gj, kml, gpx = tmp_path / "f.geojson", tmp_path / "f.kml", tmp_path / "f.gpx"
    status, _, err = cli("track", path, "--geojson", gj, "--kml", kml, "--gpx", gpx)
    assert status == 0, err
    feats = json.loads(gj.read_text())["features"]
    (poly,) = [f for f in feats if f["properties"]["kind"] == "fence"]
    ring = poly["geometry"]["coordinates"][0]
    assert ring[0] == ring[-1] and len(ring) == 5 and _ring_area(ring) > 0  # closed, counter-clockwise
    assert sorted(map(tuple, ring[:-1])) == sorted((lon, lat) for lat, lon in
                                                   [(47.0, 8.0), (47.0, 8.01), (46.99, 8.01), (46.99, 8.0)])
    (circle,) = [f for f in feats if f["properties"]["kind"] == "fence-circle"]
    assert circle["geometry"]["coordinates"] == [8.005, 46.995] and circle["properties"]["radius_m"] == 50.0
    assert circle["properties"]["inclusion"] is False
    assert [f["geometry"]["coordinates"] for f in feats if f["properties"]["kind"] == "rally"] == \
        [[8.002, 46.996, 30.0], [8.002, 46.9961, 30.0]]
    root = ET.parse(kml).getroot()
    (outer,) = root.iter(f"{KML}LinearRing")
    pts = outer.findtext(f"{KML}coordinates").split()  # type: ignore[union-attr]
    assert pts[0] == pts[-1] and len(pts) == 5
    names = [n.text for n in root.iter(f"{KML}name")]
    assert "rally 1" in names and any(n and n.startswith("fence circle exclusion r=50.0") for n in names)
    root = ET.parse(gpx).getroot()
    rtes = {r.findtext(f"{GPX}name"): r for r in root.findall(f"{GPX}rte")}
    fence = rtes["fence inclusion"].findall(f"{GPX}rtept")
    assert len(fence) == 5 and fence[0].attrib == fence[-1].attrib  # the polygon closed
    assert [w.findtext(f"{GPX}name") for w in root.findall(f"{GPX}wpt")] == ["rally 1", "rally 2",
                                                                            "fence circle exclusion"]


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_fence_and_rally_that_are_not_numbers(tmp_path: Path, cli: Cli, bad: float) -> None:
    """MISSION_ITEM (float coordinates) uploads built here: a polygon whose vertex count is `bad`, a
    3-vertex polygon with one `bad` latitude, a circle at a `bad` centre, a breach return point with a `bad`
    longitude, a rally point at `bad` and one at 47.0, 8.0 with a `bad` altitude. Each place that is not a
    number is left out of the .plan with a warning (the vertex count crashed `int()`, the rally altitude
    the KML writer); only the last rally point remains, and every file is strict JSON or parses as XML."""
    ex = Exchange()
    ex.heartbeats(vehicle_type=2, autopilot=3)
    fence = [(5001, bad, 47.0, 8.0), (5001, 3.0, bad, 8.0), (5001, 3.0, 47.1, 8.0), (5001, 3.0, 47.1, 8.1),
             (5004, 50.0, bad, 8.0), (5000, 0.0, 47.0, bad)]
    ex.send("gcs", "MISSION_COUNT", 1, 1, len(fence), 1)
    for seq, (cmd, p1, lat, lon) in enumerate(fence):
        ex.send("veh", "MISSION_REQUEST_INT", 255, 190, seq, 1)
        ex.send("gcs", "MISSION_ITEM", 1, 1, seq, 0, cmd, 0, 1, p1, 0, 0, 0, lat, lon, 0.0, 1)
    ex.send("veh", "MISSION_ACK", 255, 190, 0, 1)
    ex.send("gcs", "MISSION_COUNT", 1, 1, 2, 2)
    for seq, (lat, lon, alt) in enumerate([(bad, bad, bad), (47.0, 8.0, bad)]):
        ex.send("veh", "MISSION_REQUEST_INT", 255, 190, seq, 2)
        ex.send("gcs", "MISSION_ITEM", 1, 1, seq, 0, 5100, 0, 1, 0, 0, 0, 0, lat, lon, alt, 2)
    ex.send("veh", "MISSION_ACK", 255, 190, 0, 2)
    ex.send("veh", "GLOBAL_POSITION_INT", 1000, 469970000, 80030000, 500_000, 20_000, 0, 0, 0, 0)
    path = ex.tlog(tmp_path / "bad.tlog")
    plan, gj, kml, gpx = (tmp_path / f"f.{x}" for x in ("plan", "geojson", "kml", "gpx"))
    status, _, err = cli("mission", path, "--plan", plan)
    assert status == 0, err
    assert err.count("left out") == 5, err  # the count, the polygon, the circle, the return, rally item 0
    strict = {"parse_constant": lambda c: pytest.fail(f"{c} in a JSON file")}
    doc = json.loads(plan.read_text(), **strict)  # type: ignore[arg-type]
    assert doc["geoFence"] == {"circles": [], "polygons": [], "version": 2}
    assert doc["rallyPoints"]["points"] == [[47.0, 8.0, None]]
    status, _, err = cli("track", path, "--geojson", gj, "--kml", kml, "--gpx", gpx)
    assert status == 0, err
    feats = json.loads(gj.read_text(), **strict)["features"]  # type: ignore[arg-type]
    assert [f["geometry"]["coordinates"] for f in feats if f["properties"]["kind"] == "rally"] == [[8.0, 47.0]]
    assert [n.text for n in ET.parse(kml).getroot().iter(f"{KML}name") if n.text and "rally" in n.text] == ["rally 1"]
    assert [w.attrib for w in ET.parse(gpx).getroot().findall(f"{GPX}wpt")] == [{"lat": "47.0000000",
                                                                                 "lon": "8.0000000"}]


def test_tracks_are_bounded(tmp_path: Path, dialect: Dialect, monkeypatch: pytest.MonkeyPatch) -> None:
    """Past MAX_POINTS a track keeps every second point, and from then on every second position."""
    monkeypatch.setattr(track_mod, "MAX_POINTS", 40)
    with open_capture(str(TAKEOVER)) as r:
        result = track_mod.tracks((f for f in Dissector(dialect).run(r) if type(f) is not Anomaly), dialect)
    (t,) = result.tracks
    assert t.seen == 300 and t.stride == 8 and len(t.points) == math.ceil(300 / 8) <= 40
    records = [m.index for m in read_pcap(TAKEOVER) if m.name == "GLOBAL_POSITION_INT"]  # pymavlink's reading
    assert [p.record for p in t.points] == records[::8]


def test_usage_and_stdout(tmp_path: Path, cli: Cli) -> None:
    status, _, err = cli("track", TAKEOVER)
    assert status == 2 and "--geojson" in err
    status, out, err = cli("track", TAKEOVER, "--gpx", "-")
    assert status == 0 and ET.fromstring(out.split("?>", 1)[1]).tag == f"{GPX}gpx"
    status, _, err = cli("track", TAKEOVER, "--gpx", "-", "--kml", "-")
    assert status == 2 and "stdout" in err
    doc = cli.json("track", TAKEOVER, "--kml", tmp_path / "x.kml")
    assert doc["tracks"][0]["positions"] == 300 and doc["mission_transfer"] is None  # cleared by the takeover
    assert doc["history_mission_transfer"] == 1 and doc["cleared"]["mission"]["how"] == "clear-all"
    status, out, _ = cli("track", TAKEOVER, "--kml", tmp_path / "y.kml")
    assert status == 0 and "the vehicle holds no mission since" in out and "drawn as history" in out
