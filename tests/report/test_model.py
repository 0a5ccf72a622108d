"""The report's facts on a small flight built by hand (tests/support/report_flight.py): every expected value
below is read off that construction (or computed here with hashlib), not from mavscope."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.support import report_flight as fl
from tests.support.flows import T0


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, int]:
    tmp = tmp_path_factory.mktemp("report")
    cap, flow = fl.write(tmp)
    params = tmp / "other.param"
    params.write_text("ARMING_CHECK,1\nONLY_THERE,2\n")
    status, _, err = Cli()("report", str(cap), "-o", str(tmp / "r.html"), "--json", str(tmp / "r.json"),
                           "--params-file", str(params))
    assert status == 0, err
    return cap, json.loads((tmp / "r.json").read_text()), len(flow.entries)


def test_custody_hashes_the_files(built: tuple[Path, dict, int]) -> None:
    cap, doc, _ = built
    data = cap.read_bytes()
    one = doc["inputs"][0]
    assert one["file"] == {"path": str(cap), "name": "flight.tlog", "size": len(data),
                           "sha256": hashlib.sha256(data).hexdigest()}
    assert doc["custody"]["inputs"] == [one["file"]]
    assert doc["schema"] == "mavscope-report" and doc["schema_version"] == 1
    other = doc["custody"]["params_file"]
    assert other["sha256"] == hashlib.sha256(b"ARMING_CHECK,1\nONLY_THERE,2\n").hexdigest()
    top = [d for d in doc["custody"]["dialects"] if d["included_by"] is None]
    assert top[0]["name"] == "all.xml"
    for d in doc["custody"]["dialects"]:
        assert d["sha256"] == hashlib.sha256(Path(d["path"]).read_bytes()).hexdigest()
    assert any(d["name"] == "common.xml" for d in doc["custody"]["dialects"])  # (all.xml includes it)


def test_span_and_frames(built: tuple[Path, dict, int]) -> None:
    _, doc, entries = built
    one = doc["inputs"][0]
    assert one["frames"] == entries  # one frame a tlog entry
    assert one["kind"] == "tlog"
    assert one["span"]["start"] == pytest.approx(T0 + 0.01)  # the first entry, 10 ms after T0
    assert one["span"]["end"] == pytest.approx(T0 + 0.01 * entries)


def test_summary(built: tuple[Path, dict, int]) -> None:
    s = built[1]["inputs"][0]["summary"]
    (v,) = s["vehicles"]
    assert (v["sysid"], v["compid"], v["type"], v["autopilot"], v["armed"]) == (1, 1, "QUADROTOR", "ARDUPILOTMEGA",
                                                                                False)
    assert v["firmware"]["flight"] == "4.5.6 (type 255)"
    assert [(g["sysid"], g["compid"]) for g in s["ground_stations"]] == [(255, 190)]
    rows = {(tuple(r["from"]), tuple(r["to"]), r["what"]): (r["count"], r["accepted"]) for r in s["commanders"]}
    assert rows[((255, 190), (1, 1), "COMPONENT_ARM_DISARM")] == (1, 1)
    assert rows[((255, 190), (1, 1), "set ARMING_CHECK")] == (1, 1)
    assert rows[((255, 190), (1, 1), "upload mission")] == (1, 1)
    assert {(r["sysid"], r["compid"]): r["verdict"] for r in s["signing"]} == {(1, 1): "unsigned",
                                                                               (255, 190): "unsigned"}


def test_missions_uploaded_against_reached(built: tuple[Path, dict, int]) -> None:
    m = built[1]["inputs"][0]["missions"]
    t, fence, rally = m["transfers"]
    assert [(x["mission_type"], x["count"], x["outcome"]) for x in (fence, rally)] == [("FENCE", 4, "complete"),
                                                                                      ("RALLY", 1, "complete")]
    assert "reached" not in fence  # (only mission uploads are held against the items reached)
    assert (t["direction"], t["mission_type"], t["count"], t["from"], t["to"]) == ("upload", "MISSION", 2,
                                                                                   [255, 190], [1, 1])
    assert [(i["seq"], i["command"]) for i in t["items"]] == [(0, "NAV_WAYPOINT"), (1, "NAV_WAYPOINT")]
    assert t["reached"] == [1]
    assert m["progress"] == [{"sysid": 1, "reached": [1], "current": []}]


def test_the_map_has_the_track_mission_fence_and_rally(built: tuple[Path, dict, int]) -> None:
    features = built[1]["inputs"][0]["map"]["features"]
    kinds = sorted(f["properties"]["kind"] for f in features)
    # ArduPilot's item 0 is home, item 1 the one waypoint; the fence one polygon of the 4 vertices (closed)
    assert kinds == ["fence", "home", "rally", "track", "waypoint"]
    (fence,) = [f for f in features if f["properties"]["kind"] == "fence"]
    ring = fence["geometry"]["coordinates"][0]
    want = {(round((fl.LON + dx) / 1e7, 7), round((fl.LAT + dy) / 1e7, 7)) for dy, dx in fl.FENCE}
    assert {(round(x, 7), round(y, 7)) for x, y in ring} == want and ring[0] == ring[-1]
    (rally,) = [f for f in features if f["properties"]["kind"] == "rally"]
    assert rally["geometry"]["coordinates"][:2] == pytest.approx([(fl.LON - 500) / 1e7, (fl.LAT + 500) / 1e7])
    (home,) = [f for f in features if f["properties"]["kind"] == "home"]
    assert home["geometry"]["coordinates"][:2] == pytest.approx([fl.LON / 1e7, fl.LAT / 1e7])


def test_plots_hold_the_values_sent(built: tuple[Path, dict, int]) -> None:
    plots = {p["field"]: p for p in built[1]["inputs"][0]["plots"]}
    alt = plots["GLOBAL_POSITION_INT.relative_alt"]
    assert (alt["count"], alt["min"], alt["max"], alt["divisor"], alt["unit"]) == (2, 10_000, 20_000, 1000.0, "m")
    assert (plots["VFR_HUD.groundspeed"]["min"], plots["VFR_HUD.groundspeed"]["max"]) == (3.5, 7.0)
    assert (plots["SYS_STATUS.voltage_battery"]["min"], plots["SYS_STATUS.voltage_battery"]["max"]) == (12_100, 12_600)
    assert (plots["GPS_RAW_INT.fix_type"]["min"], plots["GPS_RAW_INT.satellites_visible"]["max"]) == (3, 9)
    for p in plots.values():  # every bucket's envelope holds the values: [start, min, max], min <= max
        assert all(lo <= hi for _, lo, hi in p["buckets"])


def test_params_and_the_diff(built: tuple[Path, dict, int]) -> None:
    p = built[1]["inputs"][0]["params"]
    sets = [c for c in p["changes"] if c["what"] == "set"]
    assert [(c["name"], c["value"], c["confirmed"], c["from"], c["to"]) for c in sets] == [
        ("ARMING_CHECK", 0.0, True, [255, 190], [1, 1])]
    d = p["diff"]
    assert d["changed"] == {"ARMING_CHECK": [0.0, 1.0]}
    assert d["only_there"] == {"ONLY_THERE": 2.0}
    assert d["only_here"] == {}


def test_files_moved_with_their_hash(built: tuple[Path, dict, int]) -> None:
    (f,) = built[1]["inputs"][0]["files"]
    assert (f["path"], f["size"], f["complete"], f["direction"]) == (fl.FILE_PATH, len(fl.FILE_DATA), True, "download")
    assert f["sha256"] == hashlib.sha256(fl.FILE_DATA).hexdigest()


def test_events_name_their_frames(built: tuple[Path, dict, int]) -> None:
    cap, doc, _ = built
    events = doc["inputs"][0]["events"]["events"]
    (text,) = [e for e in events if e["kind"] == "statustext"]
    assert fl.TEXT in text["text"]
    assert text["show"] == f"mavscope read {cap} -Y 'frame.number == {text['frame']}' -V"
    arm = [e for e in events if e["kind"] == "command"]
    assert arm and arm[0]["frame"] == 4  # the GCS's COMMAND_LONG is the flow's 4th entry
