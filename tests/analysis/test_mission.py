"""Mission reconstruction on captures whose transfers are known; the QGroundControl plan export."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import CAPTURES, Cli
from tests.support.captures import truth

RESEND = str(CAPTURES / "mission_resend.pcap")


def test_transfers_match_the_truth(cli: Cli) -> None:
    doc = cli.json("mission", RESEND)
    got = doc["transfers"]
    want = truth("mission_resend.pcap")["transfers"]
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g["from"] == w["from"] and g["to"] == w["to"]
        assert (g["direction"], g["mission_type"], g["count"], g["complete"]) == \
            (w["direction"], w["mission_type"], w["count"], w["complete"])
        if "commands" in w:
            assert [i["command_id"] for i in g["items"]] == w["commands"]
        if "result" in w:
            assert g["result"] == w["result"] and g["reason"].startswith("NACK")
    upload = got[1]
    assert upload["resent_items"] == [2]
    assert [i["seq"] for i in upload["items"]] == [0, 1, 2, 3]  # the resent item is kept once
    assert len(upload["items"][2]["frames"]) == 2
    for item, (lat, lon) in zip(upload["items"], truth("mission_resend.pcap")["transfers"][1]["degrees"]):
        assert item["x"] == pytest.approx(lat, abs=1e-7) and item["y"] == pytest.approx(lon, abs=1e-7)
        assert item["units"] == "deg"
    assert upload["items"][1]["param_labels"][:2] == ["Hold", "Accept Radius"]
    assert upload["items"][2]["params"][:2] == [5.0, 2.0]
    abandoned = got[3]
    assert abandoned["complete"] is False and abandoned["reason"].startswith("abandoned")
    assert abandoned["missing"] == [[1, 2]] and len(abandoned["items"]) == 1
    assert all(isinstance(n, int) for t in got for n in t["frames"])


def test_px4_session_upload(cli: Cli) -> None:
    doc = cli.json("mission", str(CAPTURES / "px4_sitl_udp.pcap"))
    (t,) = doc["transfers"]
    assert t["complete"] and t["count"] == 4 and t["direction"] == "upload"
    assert [i["command"] for i in t["items"]] == ["MAV_CMD_NAV_TAKEOFF", "MAV_CMD_NAV_WAYPOINT",
                                                  "MAV_CMD_NAV_WAYPOINT", "MAV_CMD_NAV_RETURN_TO_LAUNCH"]
    assert t["items"][0]["x"] == pytest.approx(47.3977419)


def test_plan_export(cli: Cli, tmp_path: Path) -> None:
    out = tmp_path / "m.plan"
    status, text, err = cli("mission", RESEND, "--plan", str(out))
    assert status == 0, err
    plan = json.loads(out.read_text())
    assert plan["fileType"] == "Plan" and plan["version"] == 1 and plan["groundStation"] == "QGroundControl"
    assert {"geoFence", "rallyPoints", "mission"} <= set(plan)
    items = plan["mission"]["items"]
    # the last complete mission transfer: the 4-item upload
    assert [i["command"] for i in items] == [22, 16, 16, 16]
    first = items[1]
    assert first["type"] == "SimpleItem" and len(first["params"]) == 7 and first["doJumpId"] == 2
    assert first["frame"] == 3 and first["AltitudeMode"] == 1 and first["Altitude"] == 25.0
    assert first["params"][4] == pytest.approx(47.3981012, abs=1e-7)
    assert first["params"][3] is None  # NaN yaw: "unchanged"
    assert len(plan["mission"]["plannedHomePosition"]) == 3


def test_plan_without_mission_is_an_error(cli: Cli, tmp_path: Path) -> None:
    status, _, err = cli("mission", str(CAPTURES / "clock_skew.pcap"), "--plan", str(tmp_path / "x.plan"))
    assert status == 2 and "no mission, fence or rally items" in err


def test_text_table(cli: Cli) -> None:
    status, out, _ = cli("mission", RESEND)
    assert status == 0
    assert "Transfer 2: upload" in out and "resent items [2]" in out and "Accept Radius" in out
    assert "47.3981012°" in out and "INCOMPLETE: abandoned" in out
