"""Tracks, missions and fences as GeoJSON (RFC 7946), KML 2.2 and GPX 1.1, written with the standard library.

- GeoJSON: a FeatureCollection; coordinates are [longitude, latitude, altitude] (RFC 7946 section 3.1.1).
  A track is a LineString (a Point when it has one position) whose `properties.times` gives each
  position's time (ISO 8601 UTC, null where the capture has none); the mission is a LineString through its
  waypoints plus one Point per item; fence polygons are Polygons (exterior ring counter-clockwise, closed,
  as section 3.1.6 asks); a fence circle is a Point with `radius_m` (GeoJSON has no circle); rally points
  and home are Points. `properties.kind` says which is which.
- KML: a track is a gx:Track (`when` and `gx:coord` per position, the Google extension every KML viewer
  reads), the mission a LineString and Placemarks, fences Polygons, circles and rally points Placemarks.
- GPX: tracks as <trk> with timed <trkpt>, the mission as a <rte>, a fence polygon as a closed <rte>, home,
  rally points and fence circles as <wpt>.
Altitudes: tracks carry metres above mean sea level; mission items their z as the mission gives it (relative
to home in MAV_FRAME_GLOBAL_RELATIVE_ALT, `properties.frame` says).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from datetime import datetime, timezone
from typing import Any
from xml.etree import ElementTree as ET

from mavscope.analysis.mission import PlanExport
from mavscope.analysis.track import Track, Tracks
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.semantics import enum_name

GPX_NS = "http://www.topografix.com/GPX/1/1"
KML_NS = "http://www.opengis.net/kml/2.2"
GX_NS = "http://www.google.com/kml/ext/2.2"
HOME_SOURCES = ("HOME_POSITION", "mission item 0 (ArduPilot home)")  # PlanExport.home_source values that are a home
RELATIVE_FRAMES = frozenset({3})  # MAV_FRAME_GLOBAL_RELATIVE_ALT (the .plan's float form of the *_INT frames)


def xsd_time(t: float | None) -> str | None:
    """ISO 8601 UTC with milliseconds, None for no time or one the calendar cannot hold."""
    if t is None or not math.isfinite(t):
        return None
    try:
        dt = datetime.fromtimestamp(t, tz=timezone.utc)
    except (OverflowError, OSError, ValueError):
        return None
    return dt.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _num(v: object) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def _missions(tracks: Tracks, dialect: Dialect) -> Iterator[tuple[list[tuple[int, str, float, float, float, int]],
                                                                    dict[str, object]]]:
    """The mission the vehicle holds ("current") and the one it held before it was cleared ("history", with
    `until`, the time it was cleared): their waypoints and the properties that say which."""
    yield list(_waypoints(tracks.plan, dialect)), {"state": "current"}
    if tracks.history is not None:
        yield list(_waypoints(tracks.history, dialect)), {"state": "history", "until": xsd_time(tracks.history_until)}


def _mission_name(props: dict[str, object]) -> str:
    if props["state"] == "current":
        return "mission"
    return f"mission (history: cleared {props['until']})" if props["until"] else "mission (history: cleared)"


def _waypoints(plan: PlanExport | None, dialect: Dialect) -> Iterator[tuple[int, str, float, float, float, int]]:
    """(seq, command name, lat, lon, z, frame) of the mission items with a position."""
    if plan is None:
        return
    mission: Any = plan.plan["mission"]
    for item in mission["items"]:
        params = item.get("params") or []
        lat, lon, z = (_num(params[i]) if len(params) > i else None for i in (4, 5, 6))
        if lat is None or lon is None or (lat == 0 and lon == 0) or not (-90 <= lat <= 90 and -180 <= lon <= 180):
            continue
        name = enum_name(dialect, "MAV_CMD", int(item["command"])).removeprefix("MAV_CMD_")
        yield int(item["doJumpId"]), name, lat, lon, z or 0.0, int(item.get("frame", 0))


def _home(tracks: Tracks) -> tuple[float, float, float] | None:
    """Home where the capture says it (HOME_POSITION, ArduPilot's mission item 0), not a .plan's stand-in."""
    if tracks.plan is None or tracks.plan.home_source not in HOME_SOURCES:
        return None
    mission: Any = tracks.plan.plan["mission"]
    home = mission.get("plannedHomePosition")
    if not home:
        return None
    lat, lon, alt = (_num(v) for v in home)
    return None if lat is None or lon is None else (lat, lon, alt or 0.0)


def _fence(tracks: Tracks) -> dict[str, list[Any]]:
    if tracks.plan is None:
        return {"polygons": [], "circles": [], "rally": []}
    fence: Any = tracks.plan.plan["geoFence"]
    rally: Any = tracks.plan.plan["rallyPoints"]
    return {"polygons": list(fence.get("polygons", [])), "circles": list(fence.get("circles", [])),
            "rally": list(rally.get("points", []))}


def _ccw(ring: list[list[float]]) -> list[list[float]]:
    """The ring [[lon, lat]...] closed and counter-clockwise (positive shoelace area)."""
    if ring and ring[0] != ring[-1]:
        ring = ring + [ring[0]]
    area = sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(ring, ring[1:]))
    return ring[::-1] if area < 0 else ring


def _label(t: Track) -> str:
    return f"system {t.sysid}/{t.compid} ({t.source})"


# --- GeoJSON ----------------------------------------------------------------------------------------

def geojson(tracks: Tracks, dialect: Dialect) -> dict[str, object]:
    features: list[dict[str, object]] = []

    def feature(geometry: dict[str, object], **props: object) -> None:
        features.append({"type": "Feature", "geometry": geometry, "properties": props})

    for t in tracks.tracks:
        coords = [[p.lon, p.lat, p.alt] for p in t.points]
        geom: dict[str, object] = {"type": "LineString", "coordinates": coords} if len(coords) > 1 else \
            {"type": "Point", "coordinates": coords[0]}
        feature(geom, kind="track", name=_label(t), sysid=t.sysid, compid=t.compid, source=t.source,
                times=[xsd_time(p.time) for p in t.points], frames=[p.record for p in t.points],
                positions=t.seen, every=t.stride)
    for wps, state in _missions(tracks, dialect):
        if len(wps) > 1:
            feature({"type": "LineString", "coordinates": [[lon, lat, z] for _, _, lat, lon, z, _ in wps]},
                    kind="mission", name=_mission_name(state), **state)
        for seq, name, lat, lon, z, frame in wps:
            feature({"type": "Point", "coordinates": [lon, lat, z]}, kind="waypoint", name=f"{seq} {name}", seq=seq,
                    command=name, frame=frame, **state)
    home = _home(tracks)
    if home is not None:
        feature({"type": "Point", "coordinates": [home[1], home[0], home[2]]}, kind="home", name="home")
    fence = _fence(tracks)
    for poly in fence["polygons"]:
        ring = _ccw([[lon, lat] for lat, lon in poly["polygon"]])
        if len(ring) >= 4:
            feature({"type": "Polygon", "coordinates": [ring]}, kind="fence", inclusion=poly["inclusion"],
                    name="fence " + ("inclusion" if poly["inclusion"] else "exclusion"))
    for c in fence["circles"]:
        lat, lon = c["circle"]["center"]
        feature({"type": "Point", "coordinates": [lon, lat]}, kind="fence-circle", inclusion=c["inclusion"],
                radius_m=c["circle"]["radius"], name="fence circle " + ("inclusion" if c["inclusion"] else "exclusion"))
    for i, (lat, lon, alt) in enumerate(fence["rally"], 1):
        feature({"type": "Point", "coordinates": [lon, lat] if alt is None else [lon, lat, alt]}, kind="rally",
                name=f"rally {i}")
    return {"type": "FeatureCollection", "features": features}


# --- KML --------------------------------------------------------------------------------------------

def _placemark(parent: ET.Element, name: str, description: str = "") -> ET.Element:
    pm = ET.SubElement(parent, f"{{{KML_NS}}}Placemark")
    ET.SubElement(pm, f"{{{KML_NS}}}name").text = name
    if description:
        ET.SubElement(pm, f"{{{KML_NS}}}description").text = description
    return pm


def kml(tracks: Tracks, dialect: Dialect) -> str:
    ET.register_namespace("", KML_NS)
    ET.register_namespace("gx", GX_NS)
    root = ET.Element(f"{{{KML_NS}}}kml")
    doc = ET.SubElement(root, f"{{{KML_NS}}}Document")
    ET.SubElement(doc, f"{{{KML_NS}}}name").text = "mavscope track"
    k = f"{{{KML_NS}}}"
    for t in tracks.tracks:
        pm = _placemark(doc, _label(t), f"{t.seen} positions" + (f", every {t.stride}th kept" if t.stride > 1 else ""))
        if all(xsd_time(p.time) is not None for p in t.points):
            track = ET.SubElement(pm, f"{{{GX_NS}}}Track")
            ET.SubElement(track, f"{k}altitudeMode").text = "absolute"
            for p in t.points:
                ET.SubElement(track, f"{k}when").text = xsd_time(p.time)
            for p in t.points:
                ET.SubElement(track, f"{{{GX_NS}}}coord").text = f"{p.lon:.7f} {p.lat:.7f} {p.alt:.3f}"
        else:
            line = ET.SubElement(pm, f"{k}LineString")
            ET.SubElement(line, f"{k}altitudeMode").text = "absolute"
            ET.SubElement(line, f"{k}coordinates").text = " ".join(
                f"{p.lon:.7f},{p.lat:.7f},{p.alt:.3f}" for p in t.points)
    points: list[tuple[str, float, float, float]] = []
    for wps, state in _missions(tracks, dialect):
        if len(wps) > 1:
            line = ET.SubElement(_placemark(doc, _mission_name(state)), f"{k}LineString")
            ET.SubElement(line, f"{k}altitudeMode").text = "relativeToGround"
            ET.SubElement(line, f"{k}coordinates").text = " ".join(f"{lon:.7f},{lat:.7f},{z:.3f}"
                                                                     for _, _, lat, lon, z, _ in wps)
        mark = "" if state["state"] == "current" else " (history)"
        points += [(f"{seq} {name}{mark}", lat, lon, z) for seq, name, lat, lon, z, _ in wps]
    home = _home(tracks)
    if home is not None:
        points.append(("home", *home))
    fence = _fence(tracks)
    points += [(f"rally {i}", lat, lon, alt or 0.0) for i, (lat, lon, alt) in enumerate(fence["rally"], 1)]
    points += [(f"fence circle {'inclusion' if c['inclusion'] else 'exclusion'} r={c['circle']['radius']} m",
                *c["circle"]["center"], 0.0) for c in fence["circles"]]
    for name, lat, lon, z in points:
        pt = ET.SubElement(_placemark(doc, name), f"{k}Point")
        ET.SubElement(pt, f"{k}coordinates").text = f"{lon:.7f},{lat:.7f},{z:.3f}"
    for poly in fence["polygons"]:
        pm = _placemark(doc, "fence " + ("inclusion" if poly["inclusion"] else "exclusion"))
        ring = _ccw([[lon, lat] for lat, lon in poly["polygon"]])
        outer = ET.SubElement(ET.SubElement(ET.SubElement(pm, f"{k}Polygon"), f"{k}outerBoundaryIs"),
                              f"{k}LinearRing")
        ET.SubElement(outer, f"{k}coordinates").text = " ".join(f"{lon:.7f},{lat:.7f},0" for lon, lat in ring)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


# --- GPX --------------------------------------------------------------------------------------------

def gpx(tracks: Tracks, dialect: Dialect) -> str:
    ET.register_namespace("", GPX_NS)
    g = f"{{{GPX_NS}}}"
    root = ET.Element(f"{g}gpx", {"version": "1.1", "creator": "mavscope"})
    home = _home(tracks)
    fence = _fence(tracks)

    def wpt(tag: str, parent: ET.Element, lat: float, lon: float, ele: float | None, name: str,
            time: str | None = None, desc: str = "") -> None:
        el = ET.SubElement(parent, f"{g}{tag}", {"lat": f"{lat:.7f}", "lon": f"{lon:.7f}"})
        if ele is not None:  # the schema's order: ele, time, name, desc
            ET.SubElement(el, f"{g}ele").text = f"{ele:.3f}"
        if time is not None:
            ET.SubElement(el, f"{g}time").text = time
        if name:
            ET.SubElement(el, f"{g}name").text = name
        if desc:
            ET.SubElement(el, f"{g}desc").text = desc

    if home is not None:
        wpt("wpt", root, home[0], home[1], home[2], "home")
    for i, (lat, lon, alt) in enumerate(fence["rally"], 1):
        wpt("wpt", root, lat, lon, alt, f"rally {i}")
    for c in fence["circles"]:
        lat, lon = c["circle"]["center"]
        wpt("wpt", root, lat, lon, None, "fence circle " + ("inclusion" if c["inclusion"] else "exclusion"),
            desc=f"radius {c['circle']['radius']} m")
    for wps, state in _missions(tracks, dialect):
        if not wps:
            continue
        rte = ET.SubElement(root, f"{g}rte")
        ET.SubElement(rte, f"{g}name").text = _mission_name(state)
        for seq, name, lat, lon, z, frame in wps:
            wpt("rtept", rte, lat, lon, z, f"{seq} {name}",
                desc="altitude relative to home" if frame in RELATIVE_FRAMES else "")
    for poly in fence["polygons"]:
        rte = ET.SubElement(root, f"{g}rte")
        ET.SubElement(rte, f"{g}name").text = "fence " + ("inclusion" if poly["inclusion"] else "exclusion")
        pts = list(poly["polygon"])
        for i, (lat, lon) in enumerate(pts + pts[:1]):
            wpt("rtept", rte, lat, lon, None, f"{i % len(pts)}")
    for t in tracks.tracks:
        trk = ET.SubElement(root, f"{g}trk")
        ET.SubElement(trk, f"{g}name").text = _label(t)
        seg = ET.SubElement(trk, f"{g}trkseg")
        for p in t.points:
            wpt("trkpt", seg, p.lat, p.lon, p.alt, "", xsd_time(p.time))
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"
