"""Every command's JSON, CSV, table and file output shows a float32 field of a frame as the shortest text
that reads back as the same float32 (issue 35 item 15: 30.48, not 30.479999542236328), and a value made
from it keeps that text: `commands`, `mission` (and its .plan), `events`, `params`, `plot`, `track` (and
its GeoJSON), `export -T csv`, `sql` (a FLOAT column), `read`; `stats`, `timeline`, `objects`, `audit` and
`batch` never show a widened float32 either. Both engines print the same (stats, read, export, sql, the
analyses).

The capture is built with pymavlink (tests/support/flows.py): COMMAND_LONG and COMMAND_INT parameters,
MISSION_ITEM_INT param1..4 and z, a legacy MISSION_ITEM rally point (x, y, z float32 too), PARAM_VALUE
and PARAM_SET, ATTITUDE, VFR_HUD, LOCAL_POSITION_NED, NAMED_VALUE_FLOAT and HOME_POSITION (a float[4]
array), each holding the float32s nearest 30.48, 0.1, 1e-5, FLT_MAX, -0.0 and NaN.

The expected texts are derived without mavscope: numpy's float32 (Dragon4, shortest unique digits) gives
the digits, `str(numpy.float32(x))`, and Python's float repr lays them out (`repr(float(digits))`: the
double nearest a decimal of at most 9 digits has those digits as its repr); the table SHORTEST below says
by hand what that gives. The widened forms that must not appear are the double of the float32, by a
struct round trip (`struct.unpack("<f", struct.pack("<f", x))`), written by repr: 30.479999542236328.
"""

from __future__ import annotations

import csv
import json
import math
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from tests.conftest import Cli
from tests.support.flows import T0, Sender, write_tlog

FLT_MAX = 3.4028234663852886e38  # (2 - 2**-23) * 2**127, the largest float32
NAN = math.nan
LAT, LON = 47.3977419, 8.5455938
VALUES = (30.48, 0.1, 1e-5, FLT_MAX, -0.0)
# by hand: the shortest decimal of each float32 (30.48: the float32 30.479999542236328 is 4.6e-7 from it,
# within its half step 9.5e-7; 0.1 and 1e-05 likewise; FLT_MAX needs 8 digits; -0.0 keeps its sign), as
# Python's repr lays out a number; MISSION_ITEM's float32 latitude and longitude need 8 and 7 digits
SHORTEST = {30.48: "30.48", 0.1: "0.1", 1e-5: "1e-05", FLT_MAX: "3.4028235e+38", -0.0: "-0.0",
            LAT: "47.397743", LON: "8.545594"}


def _widened(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def _shortest(x: float) -> float:
    """The double nearest the shortest decimal of float32 `x` (what a JSON reader makes of it)."""
    return float(str(np.float32(x)))


# the widened doubles (30.479999542236328, 0.10000000149011612, 9.999999747378752e-06,
# 3.4028234663852886e+38, 47.39774322509766, 8.545593738555908) and the digits any layout of them shows
WIDENED = {_widened(x) for x in (*VALUES, LAT, LON) if _widened(x) != _shortest(x)}
WIDENED_DIGITS = re.compile("|".join(re.escape(repr(w).split("e")[0]) for w in WIDENED))


def test_the_expectations() -> None:
    """The two derivations agree with the table written by hand, and every widened form differs."""
    for x, text in SHORTEST.items():
        assert repr(_shortest(x)) == text, x
        assert np.float32(float(text)) == np.float32(x)  # reads back as the same float32
    assert len(WIDENED) == 6 and "30.479999542236328" in {repr(w) for w in WIDENED}


def capture(tmp: Path) -> str:
    veh, gcs = Sender(1, 1), Sender(255, 190)
    p, q, r, big, nz = VALUES
    e: list[tuple[float, object]] = []

    def at(sender: Sender, msg: object) -> None:
        e.append((T0 + 0.01 * len(e), sender.pack(msg)))

    at(veh, v2.MAVLink_heartbeat_message(2, 12, 0, 0, 4, 3))  # a PX4 quadrotor
    at(gcs, v2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))
    for i, (name, value) in enumerate(((b"RTL_ALT", p), (b"WPNAV_SPEED", q), (b"EPS", r), (b"BIG", big))):
        at(veh, v2.MAVLink_param_value_message(name, value, 9, 4, i))
    at(gcs, v2.MAVLink_param_set_message(1, 1, b"RTL_ALT", q, 9))
    at(veh, v2.MAVLink_param_value_message(b"RTL_ALT", q, 9, 4, 0))
    for i in range(3):
        at(veh, v2.MAVLink_global_position_int_message(1000 * i, round(LAT * 1e7) + i, round(LON * 1e7), 30480,
                                                       30480, 0, 0, 0, 0))
        at(veh, v2.MAVLink_attitude_message(1000 * i, p, q, r, big, nz, NAN))
        at(veh, v2.MAVLink_vfr_hud_message(p, q, 90, 50, p, r))
        at(veh, v2.MAVLink_local_position_ned_message(1000 * i, p, q, r, big, nz, NAN))
        at(veh, v2.MAVLink_named_value_float_message(1000 * i, b"temp", p))
    at(veh, v2.MAVLink_home_position_message(round(LAT * 1e7), round(LON * 1e7), 30480, p, q, r, [p, q, r, NAN],
                                             p, q, r))
    at(gcs, v2.MAVLink_command_long_message(1, 1, 400, 0, p, q, r, big, nz, NAN, p))  # ARM, param1 30.48
    at(veh, v2.MAVLink_command_ack_message(400, 0, 0, 0, 255, 190))
    at(gcs, v2.MAVLink_command_int_message(1, 1, 0, 192, 0, 0, p, q, r, big, round(LAT * 1e7), round(LON * 1e7), p))
    at(veh, v2.MAVLink_command_ack_message(192, 0, 0, 0, 255, 190))
    # a mission upload (MISSION_ITEM_INT: param1..4 and z float32, x and y degE7) ...
    at(gcs, v2.MAVLink_mission_count_message(1, 1, 2, 0))
    for seq, params, z in ((0, (q, r, big, nz), p), (1, (p, NAN, q, r), q)):
        at(veh, v2.MAVLink_mission_request_int_message(255, 190, seq, 0))
        at(gcs, v2.MAVLink_mission_item_int_message(1, 1, seq, 6, 16, 0, 1, *params, round(LAT * 1e7) + seq,
                                                    round(LON * 1e7), z, 0))
    at(veh, v2.MAVLink_mission_ack_message(255, 190, 0, 0))
    # ... and a rally point by the legacy MISSION_ITEM (its x and y float32 degrees too)
    at(gcs, v2.MAVLink_mission_count_message(1, 1, 1, 2))
    at(veh, v2.MAVLink_mission_request_message(255, 190, 0, 2))
    at(gcs, v2.MAVLink_mission_item_message(1, 1, 0, 0, 5100, 0, 1, p, q, r, nz, LAT, LON, p, 2))
    at(veh, v2.MAVLink_mission_ack_message(255, 190, 0, 2))
    return write_tlog(tmp, e, "floats.tlog")  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def cap(tmp_path_factory: pytest.TempPathFactory) -> str:
    return capture(tmp_path_factory.mktemp("floats"))


def _numbers(doc: object) -> list[float]:
    if isinstance(doc, float):
        return [doc]
    if isinstance(doc, dict):
        return [n for v in doc.values() for n in _numbers(v)]
    if isinstance(doc, list):
        return [n for v in doc for n in _numbers(v)]
    return []


def _no_widened(text: str, where: str) -> None:
    bad = WIDENED_DIGITS.search(text)
    assert bad is None, (where, text[max(0, bad.start() - 200) : bad.end() + 100])


def _run(cli: Cli, *argv: str, engine: dict[str, str] | None = None) -> str:
    status, out, err = cli(*argv, environ={"COLUMNS": "1000", **(engine or {})})
    assert status == 0, (argv, err)
    _no_widened(out + err, " ".join(argv))
    return out


def _json(cli: Cli, *argv: str) -> dict:
    doc = json.loads(_run(cli, *argv))
    assert not WIDENED & set(_numbers(doc)), argv  # by value too, whatever the layout
    return doc


P, Q, R, BIG = (_shortest(x) for x in VALUES[:4])  # 30.48, 0.1, 1e-05, 3.4028235e+38 as a JSON reader has them


def test_commands(cli: Cli, cap: str) -> None:
    doc = _json(cli, "commands", cap, "--json")
    long, cint = doc["commands"]
    assert long["params"] == {"param1": P, "param2": Q, "param3": R, "param4": BIG, "param5": -0.0, "param6": None,
                              "param7": P, "confirmation": 0}
    assert math.copysign(1, long["params"]["param5"]) == -1
    assert {k: cint["params"][k] for k in ("param1", "param2", "param3", "param4", "z")} == \
        {"param1": P, "param2": Q, "param3": R, "param4": BIG, "z": P}
    assert cint["params"]["x"] == LAT  # an int32 on the wire (degE7): degrees, not a float32
    text = _run(cli, "commands", cap)
    for shown in ("30.48", "0.1", "1e-05", "3.4028235e+38", "47.3977419"):  # (param5 -0.0: an unlabelled 0, left out)
        assert shown in text, shown


def test_mission_json_table_and_plan(cli: Cli, cap: str, tmp_path: Path) -> None:
    doc = _json(cli, "mission", cap, "--json")
    upload, rally = doc["transfers"]
    first, second = upload["items"]
    assert (first["params"], first["z"], second["params"], second["z"]) == ([Q, R, BIG, -0.0], P, [P, None, Q, R], Q)
    assert (first["x"], first["y"]) == (LAT, LON)  # degE7 integers made degrees: 7 decimals, not float32
    item = rally["items"][0]
    assert (item["params"], item["x"], item["y"], item["z"]) == ([P, Q, R, -0.0], _shortest(LAT), _shortest(LON), P)
    table = _run(cli, "mission", cap)
    for shown in ("Hold 0.1", "Accept Radius 1e-05", "3.4028235e+38", "47.397743°", "8.545594°", "47.3977419°"):
        assert shown in table, shown
    assert re.search(r"│\s+0\.1\s+│", table)  # item 1's z, not 0.10
    plan = tmp_path / "m.plan"
    _run(cli, "mission", cap, "--plan", str(plan))
    text = plan.read_text()
    _no_widened(text, "--plan")
    p = json.loads(text)
    items = p["mission"]["items"]
    assert items[0]["params"] == [Q, R, BIG, -0.0, LAT, LON, P] and items[0]["Altitude"] == P
    assert p["rallyPoints"]["points"] == [[_shortest(LAT), _shortest(LON), P]]


def test_events(cli: Cli, cap: str) -> None:
    doc = _json(cli, "events", cap, "--json")
    commands = [e for e in doc["events"] if e.get("data", e).get("command") == "MAV_CMD_COMPONENT_ARM_DISARM"
                or "COMPONENT_ARM_DISARM" in str(e.get("text"))]
    assert commands and "(param1 30.48)" in commands[0]["text"]
    assert "(param1 30.48)" in _run(cli, "events", cap)


def test_params(cli: Cli, cap: str, tmp_path: Path) -> None:
    doc = _json(cli, "params", cap, "--json")
    assert doc["final"] == {"RTL_ALT": Q, "WPNAV_SPEED": Q, "EPS": R, "BIG": BIG}
    text = _run(cli, "params", cap)
    assert re.search(r"RTL_ALT\s+│\s+0\.1\s+│\s+30\.48\s+│", text)  # the set: its value and the one before
    out = tmp_path / "x.param"
    _run(cli, "params", cap, "--out", str(out))
    # (a parameter file writes a short enough decimal plainly: 1e-05 as 0.00001, the same digits)
    assert {"EPS,0.00001", "BIG,3.4028235e+38", "WPNAV_SPEED,0.1"} <= set(out.read_text().splitlines())


def test_plot(cli: Cli, cap: str) -> None:
    doc = _json(cli, "plot", cap, "ATTITUDE.roll", "HOME_POSITION.q[2]", "--json")
    for s in doc["series"]:
        assert (s["min"], s["max"]) == ((P, P) if s["field"] == "ATTITUDE.roll" else (R, R))
        assert all((b["min"], b["max"]) == (s["min"], s["max"]) for b in s["buckets"])
    text = _run(cli, "plot", cap, "ATTITUDE.roll", "ATTITUDE.pitch", "--width", "40", "--height", "3")
    assert "min 30.48, max 30.48" in text and "min 0.1, max 0.1" in text


def test_track(cli: Cli, cap: str, tmp_path: Path) -> None:
    _json(cli, "track", cap, "--json")
    geo = tmp_path / "t.geojson"
    _run(cli, "track", cap, "--geojson", str(geo))
    text = geo.read_text()
    _no_widened(text, "--geojson")
    points = [f["geometry"]["coordinates"] for f in json.loads(text)["features"] if f["geometry"]["type"] == "Point"]
    assert [LON, LAT, P] in points  # waypoint 1: degE7 degrees, float32 altitude
    assert [_shortest(LON), _shortest(LAT), P] in points  # the rally point: float32 degrees


@pytest.mark.parametrize("argv", [("stats", "--json"), ("stats",), ("timeline", "--json"), ("objects", "--json"),
                                  ("audit", "--json"), ("read", "-T", "json"), ("read", "-V")],
                         ids=lambda a: "-".join(a))
def test_no_widened_float32_elsewhere(cli: Cli, cap: str, argv: tuple[str, ...]) -> None:
    _run(cli, argv[0], cap, *argv[1:])


def test_batch(cli: Cli, cap: str) -> None:
    _json(cli, "batch", cap, "--json", "--", "stats")


ATTITUDE_ROW = ["30.48", "0.1", "1e-05", "3.4028235e+38", "-0.0", "nan"]  # roll..yawspeed (NaN as str() writes it)


def test_export_csv(cli: Cli, cap: str, tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    _run(cli, "export", cap, "-T", "csv", "-o", str(tmp_path / "csv"))
    folder = tmp_path / "csv" / "floats.tlog"
    for f in folder.glob("*.csv"):
        _no_widened(f.read_text(), f.name)

    def rows(name: str) -> list[dict[str, str]]:
        with open(folder / f"{name}.csv", newline="") as fh:
            return list(csv.DictReader(fh))

    att = rows("ATTITUDE")[0]
    names = ("roll", "pitch", "yaw", "rollspeed", "pitchspeed", "yawspeed")
    assert [att[f"ATTITUDE.{k}"] for k in names] == ATTITUDE_ROW
    home = rows("HOME_POSITION")[0]
    assert home["HOME_POSITION.q"] == "[30.48, 0.1, 1e-05, nan]" and home["HOME_POSITION.latitude"] == "473977419"
    item = rows("MISSION_ITEM")[0]
    assert [item[f"MISSION_ITEM.{k}"] for k in "xyz"] == ["47.397743", "8.545594", "30.48"]
    assert rows("PARAM_VALUE")[0]["PARAM_VALUE.param_value"] == "30.48"


def test_sql(cli: Cli, cap: str) -> None:
    pytest.importorskip("duckdb")
    q = "SELECT roll, pitch, yaw, rollspeed, pitchspeed, yawspeed FROM ATTITUDE ORDER BY _frame LIMIT 1"
    assert _run(cli, "sql", q, cap, "--csv").splitlines()[1].split(",") == ATTITUDE_ROW
    row = json.loads(_run(cli, "sql", q, cap, "--json"))[0]
    assert [row[k] for k in ("roll", "pitch", "yaw", "rollspeed", "pitchspeed")] == [P, Q, R, BIG, -0.0]
    assert "3.4028235e+38" in _run(cli, "sql", q, cap)
    # a DOUBLE is a double: the widened value, written by repr (a value of the query, not of the frame)
    status, out, err = cli("sql", "SELECT CAST(roll AS DOUBLE) AS d FROM ATTITUDE LIMIT 1", cap, "--csv")
    assert status == 0 and out.split() == ["d", "30.479999542236328"], err
    q = "SELECT q FROM HOME_POSITION"
    assert json.loads(_run(cli, "sql", q, cap, "--json"))[0]["q"][:3] == [P, Q, R]


ENGINE_RUNS = [("stats",), ("stats", "--json"), ("read",), ("read", "-T", "jsonl"), ("commands", "--json"),
               ("mission", "--json"), ("events", "--json"), ("audit", "--json")]


@pytest.mark.parametrize("argv", ENGINE_RUNS, ids=lambda a: "-".join(a))
def test_both_engines_alike(cli: Cli, cap: str, argv: tuple[str, ...]) -> None:
    pytest.importorskip("mavscope._native", reason="the native extension is not built")
    native = cli(argv[0], cap, *argv[1:], environ={})
    pure = cli(argv[0], cap, *argv[1:], environ={"MAVSCOPE_PURE": "1"})
    assert (native.status, native.out, native.err) == (pure.status, pure.out, pure.err)


def test_both_engines_export_and_sql_alike(cli: Cli, cap: str, tmp_path: Path) -> None:
    pytest.importorskip("mavscope._native", reason="the native extension is not built")
    pytest.importorskip("duckdb")
    files = {}
    for name, engine in (("native", {}), ("pure", {"MAVSCOPE_PURE": "1"})):
        _run(cli, "export", cap, "-T", "csv", "-o", str(tmp_path / name), engine=engine)
        files[name] = {f.name: f.read_text() for f in (tmp_path / name / "floats.tlog").glob("*.csv")}
        files[name]["sql"] = _run(cli, "sql", "SELECT * FROM ATTITUDE", cap, "--csv", engine=engine)
    assert files["native"] == files["pure"] and len(files["native"]) > 10
