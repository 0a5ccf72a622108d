"""Mission protocol cases the real captures do not hold, built with pymavlink (mission_exchange.py).

Each test builds an exchange the way ArduPilot, PX4, Mission Planner or QGroundControl run it and states
what a correct reconstruction must say; the expectations follow from how the input was built.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.analysis.mission_exchange import Exchange, item_int
from tests.conftest import Cli

VEH, GCS = (1, 1), (255, 190)
# MAV_MISSION_RESULT
ACCEPTED, ERROR, UNSUPPORTED, DENIED, INVALID_SEQUENCE = 0, 1, 3, 14, 13
WAYPOINTS = [(-35.3632621 + i * 0.0001, 149.1652374 + i * 0.0002, 20.0 + i) for i in range(8)]


def upload(x: Exchange, n: int, mission_type: int = 0) -> list[int]:
    """COUNT n, then request/item pairs 0..n-1 as ArduPilot runs them (MISSION_REQUEST_INT here), then ACK."""
    records = [x.send("gcs", "MISSION_COUNT", *VEH, n, mission_type)]
    for s in range(n):
        records.append(x.send("veh", "MISSION_REQUEST_INT", *GCS, s, mission_type))
        records.append(item_int(x, "gcs", VEH, s, 16, *WAYPOINTS[s], mission_type=mission_type))
    records.append(x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, mission_type))
    return records


def test_invalid_sequence_nack_followed_by_requests_is_not_terminal(cli: Cli, tmp_path: Path) -> None:
    # Mission Planner uploads 5 items to ArduPilot. Its resend timer sends item 1 a second time after the
    # vehicle already asked for item 2: ArduPilot NACKs the stray copy with MAV_MISSION_INVALID_SEQUENCE
    # (MissionItemProtocol::handle_mission_item) and the upload goes on to MISSION_ACK ACCEPTED.
    x = Exchange()
    x.heartbeats(vehicle_type=10, autopilot=3)
    x.send("gcs", "MISSION_COUNT", *VEH, 5, 0)
    x.send("veh", "MISSION_REQUEST", *GCS, 0, 0)
    item_int(x, "gcs", VEH, 0, 16, *WAYPOINTS[0])
    x.send("veh", "MISSION_REQUEST", *GCS, 1, 0)
    first_copy = item_int(x, "gcs", VEH, 1, 16, *WAYPOINTS[1])
    x.send("veh", "MISSION_REQUEST", *GCS, 2, 0)
    stray_copy = item_int(x, "gcs", VEH, 1, 16, *WAYPOINTS[1])  # a new transmission (new MAVLink seq)
    nack = x.send("veh", "MISSION_ACK", *GCS, INVALID_SEQUENCE, 0)
    x.send("veh", "MISSION_REQUEST", *GCS, 2, 0, dt=1.0)  # ArduPilot asks again after 1 s
    for s in (2, 3, 4):
        item_int(x, "gcs", VEH, s, 16, *WAYPOINTS[s])
        if s < 4:
            x.send("veh", "MISSION_REQUEST", *GCS, s + 1, 0)
    final = x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 0)
    (t,) = cli.json("mission", x.tlog(tmp_path / "mp.tlog"))["transfers"]
    assert (t["direction"], t["count"], t["complete"], t["outcome"]) == ("upload", 5, True, "complete")
    assert t["result"] == "MAV_MISSION_ACCEPTED" and t["missing"] == []
    assert [i["seq"] for i in t["items"]] == [0, 1, 2, 3, 4] and t["resent_items"] == [1]
    assert t["items"][1]["frames"] == [first_copy, stray_copy]
    assert [(a["result"], a["frame"], a["role"]) for a in t["acks"]] == [
        ("MAV_MISSION_INVALID_SEQUENCE", nack, "continued"), ("MAV_MISSION_ACCEPTED", final, "final")]
    assert "went on after NACK MAV_MISSION_INVALID_SEQUENCE" in t["reason"]
    for item, (lat, lon, alt) in zip(t["items"], WAYPOINTS):
        assert (item["x"], item["y"], item["z"]) == (pytest.approx(lat, abs=1e-7), pytest.approx(lon, abs=1e-7), alt)


def test_nack_nothing_follows_is_the_result(cli: Cli, tmp_path: Path) -> None:
    # The vehicle refuses an item (MAV_MISSION_UNSUPPORTED) and requests nothing more; the GCS starts over
    # with 2 items, which are accepted.
    x = Exchange()
    x.heartbeats()
    x.send("gcs", "MISSION_COUNT", *VEH, 3, 0)
    x.send("veh", "MISSION_REQUEST_INT", *GCS, 0, 0)
    item_int(x, "gcs", VEH, 0, 16, *WAYPOINTS[0])
    x.send("veh", "MISSION_ACK", *GCS, UNSUPPORTED, 0)
    x.wait(2.0)
    upload(x, 2)
    refused, accepted = cli.json("mission", x.tlog(tmp_path / "nack.tlog"))["transfers"]
    assert (refused["outcome"], refused["result"], refused["complete"]) == ("nack", "MAV_MISSION_UNSUPPORTED", False)
    assert refused["reason"].startswith("NACK MAV_MISSION_UNSUPPORTED from 1/1") and refused["missing"] == [[1, 2]]
    assert accepted["complete"] and accepted["count"] == 2


def test_mavlink1_upload_with_mission_request_and_float_items(cli: Cli, tmp_path: Path) -> None:
    # A MAVLink 1 GCS: MISSION_COUNT to component 0 (any), MISSION_REQUEST / MISSION_ITEM (float degrees)
    # addressed to the autopilot, 8 items, MISSION_ACK ACCEPTED.
    x = Exchange(version=1)
    x.send("veh", "HEARTBEAT", 2, 3, 0, 0, 4, 3)
    x.send("gcs", "MISSION_COUNT", 1, 0, 8)
    for s in range(8):
        x.send("veh", "MISSION_REQUEST", *GCS, s)
        x.send("gcs", "MISSION_ITEM", *VEH, s, 3, 16, 0, 1, 0, 0, 0, 0, *WAYPOINTS[s])
    x.send("veh", "MISSION_ACK", *GCS, ACCEPTED)
    (t,) = cli.json("mission", x.tlog(tmp_path / "v1.tlog"))["transfers"]
    assert (t["from"], t["to"], t["complete"], t["missing"]) == ([255, 190], [1, 1], True, [])
    assert [i["message"] for i in t["items"]] == ["MISSION_ITEM"] * 8 and t["requests"] == 8
    for item, (lat, lon, alt) in zip(t["items"], WAYPOINTS):  # float32 on the wire: about 1e-6 degrees
        assert (item["x"], item["y"], item["z"]) == (pytest.approx(lat, abs=5e-6), pytest.approx(lon, abs=1e-5), alt)
        assert item["units"] == "deg" and item["frame"] == "MAV_FRAME_GLOBAL_RELATIVE_ALT"


def test_duplicated_frame_is_no_transfer_and_a_late_ack_answers_nothing(cli: Cli, tmp_path: Path) -> None:
    # A 2-item upload; the capture holds the MISSION_COUNT twice (the same bytes, same MAVLink seq: a
    # duplicated datagram) right after the ACK. 57 s later the GCS sends a lone MISSION_ACK to the vehicle
    # (the download it closes is not in the capture): it belongs to no transfer here.
    x = Exchange()
    x.heartbeats()
    records = upload(x, 2)
    dup = x.copy(records[0], dt=0.3)
    x.wait(57.0)
    lone = x.send("gcs", "MISSION_ACK", *VEH, ACCEPTED, 0)
    doc = cli.json("mission", x.tlog(tmp_path / "dup.tlog"))
    (t,) = doc["transfers"]
    assert t["complete"] and t["duplicate_frames"] == [dup] and doc["duplicates"] == 1
    assert lone not in t["frames"]
    (ev,) = doc["events"]
    assert (ev["kind"], ev["from"], ev["to"], ev["result"], ev["frames"]) == (
        "unmatched-ack", [255, 190], [1, 1], "MAV_MISSION_ACCEPTED", [lone])


def test_ack_after_the_transfer_timed_out_is_not_its_result(cli: Cli, tmp_path: Path) -> None:
    # The GCS sends MISSION_COUNT three times (1.5 s apart) and the vehicle never answers; 57 s later the
    # vehicle sends a MISSION_ACK: it does not answer that dead upload.
    x = Exchange()
    x.heartbeats()
    counts = [x.send("gcs", "MISSION_COUNT", *VEH, 4, 0, dt=1.5) for _ in range(3)]
    x.wait(57.0)
    late = x.send("veh", "MISSION_ACK", *GCS, ERROR, 0)
    doc = cli.json("mission", x.tlog(tmp_path / "timeout.tlog"))
    (t,) = doc["transfers"]
    assert t["frames"] == counts and t["count_resent"] == 2 and t["result"] is None
    assert (t["outcome"], t["closed"]) == ("abandoned", "timeout") and t["acks"] == []
    assert [(e["kind"], e["frames"]) for e in doc["events"]] == [("unmatched-ack", [late])]


def test_ack_of_another_mission_type_or_peer_does_not_close_a_transfer(cli: Cli, tmp_path: Path) -> None:
    x = Exchange()
    x.heartbeats()
    x.send("gcs", "MISSION_COUNT", *VEH, 1, 0)
    x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 1)  # fence type
    x.send("veh", "MISSION_ACK", 254, 190, DENIED, 0)  # to another GCS
    x.send("veh", "MISSION_REQUEST_INT", *GCS, 0, 0)
    item_int(x, "gcs", VEH, 0, 16, *WAYPOINTS[0])
    x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 0)
    doc = cli.json("mission", x.tlog(tmp_path / "peers.tlog"))
    (t,) = doc["transfers"]
    assert t["complete"] and [a["result"] for a in t["acks"]] == ["MAV_MISSION_ACCEPTED"]
    assert [(e["kind"], e["mission_type"], e["to"]) for e in doc["events"]] == [
        ("unmatched-ack", "MAV_MISSION_TYPE_FENCE", [255, 190]),
        ("unmatched-ack", "MAV_MISSION_TYPE_MISSION", [254, 190])]


@pytest.mark.parametrize("heartbeat", [True, False])
def test_vehicle_only_stream_is_a_download(cli: Cli, tmp_path: Path, heartbeat: bool) -> None:
    # One direction of a PX4 download (a raw stream, no times): the vehicle's MISSION_COUNT and items to
    # 1/2, then the vehicle itself ends it with MAV_MISSION_ERROR after items 0..1 of 4 (PX4's mission
    # manager does so when a request is unexpected). The requests are not in the capture.
    x = Exchange()
    if heartbeat:
        x.send("veh", "HEARTBEAT", 1, 12, 0, 0, 4, 3)  # PX4 fixed wing
    x.send("veh", "MISSION_COUNT", 1, 2, 4, 0)
    for s in (0, 1, 1):
        item_int(x, "veh", (1, 2), s, 16, *WAYPOINTS[s])
    x.send("veh", "MISSION_ACK", 1, 2, ERROR, 0)
    (t,) = cli.json("mission", x.raw(tmp_path / "px4.raw"))["transfers"]
    assert (t["direction"], t["direction_basis"]) == ("download", "heartbeat" if heartbeat else "component-id")
    assert (t["from"], t["to"], t["outcome"], t["result"]) == ([1, 1], [1, 2], "cancelled", "MAV_MISSION_ERROR")
    assert t["missing"] == [[2, 3]] and t["missing_count"] == 2
    assert t["resent_items"] == [1] and t["receiver_silent"] is True
    assert t["reason"].startswith("cancelled by the sender 1/1 with MAV_MISSION_ERROR after items 0..1 of 4")


def test_download_started_by_request_list(cli: Cli, tmp_path: Path) -> None:
    # QGroundControl asks twice (its first MISSION_REQUEST_LIST went unanswered), then downloads 2 items.
    x = Exchange()
    first = x.send("gcs", "MISSION_REQUEST_LIST", *VEH, 0)
    x.send("gcs", "MISSION_REQUEST_LIST", *VEH, 0, dt=1.5)
    x.send("veh", "MISSION_COUNT", *GCS, 2, 0)
    for s in range(2):
        x.send("gcs", "MISSION_REQUEST_INT", *VEH, s, 0)
        item_int(x, "veh", GCS, s, 16, *WAYPOINTS[s])
    x.send("gcs", "MISSION_ACK", *VEH, ACCEPTED, 0)
    doc = cli.json("mission", x.tlog(tmp_path / "dl.tlog"))
    (t,) = doc["transfers"]
    assert (t["direction"], t["direction_basis"]) == ("download", "request-list")
    assert (t["from"], t["to"]) == ([1, 1], [255, 190])
    assert t["complete"] and t["frames"][:2] == [first, first + 1] and doc["events"] == []


def test_fence_and_rally_uploads_and_their_plan(cli: Cli, tmp_path: Path) -> None:
    # QGroundControl-style: a fence of one inclusion polygon (4 vertices, param1 = vertex count), one
    # exclusion circle (param1 = radius) and a return point; 2 rally points. Each ACKed ACCEPTED.
    poly = [(-35.3620, 149.1640), (-35.3620, 149.1670), (-35.3645, 149.1670), (-35.3645, 149.1640)]
    x = Exchange()
    x.heartbeats(vehicle_type=2, autopilot=3)
    upload(x, 1)
    x.send("gcs", "MISSION_COUNT", *VEH, 6, 1)
    fence = [(5001, lat, lon, 0.0, (4, 0, 0, 0)) for lat, lon in poly] + [
        (5004, -35.3630, 149.1655, 0.0, (25.5, 0, 0, 0)), (5000, -35.3632, 149.1652, 30.0, (0, 0, 0, 0))]
    for s, (cmd, lat, lon, alt, params) in enumerate(fence):
        x.send("veh", "MISSION_REQUEST_INT", *GCS, s, 1)
        item_int(x, "gcs", VEH, s, cmd, lat, lon, alt, frame=5, params=params, mission_type=1)
    x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 1)
    rally = [(-35.3610, 149.1660, 50.0), (-35.3650, 149.1630, 60.0)]
    x.send("gcs", "MISSION_COUNT", *VEH, 2, 2)
    for s, (lat, lon, alt) in enumerate(rally):
        x.send("veh", "MISSION_REQUEST_INT", *GCS, s, 2)
        item_int(x, "gcs", VEH, s, 5100, lat, lon, alt, mission_type=2)
    x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 2)
    out = tmp_path / "fr.plan"
    doc = cli.json("mission", x.tlog(tmp_path / "fence.tlog"), "--plan", str(out))
    types = [(t["mission_type"], t["count"], t["complete"]) for t in doc["transfers"]]
    assert types == [("MAV_MISSION_TYPE_MISSION", 1, True), ("MAV_MISSION_TYPE_FENCE", 6, True),
                     ("MAV_MISSION_TYPE_RALLY", 2, True)]
    assert (doc["plan"]["fence_transfer"], doc["plan"]["rally_transfer"]) == (2, 3)
    plan = json.loads(out.read_text())
    (polygon,) = plan["geoFence"]["polygons"]
    assert polygon["inclusion"] is True and polygon["version"] == 1
    assert polygon["polygon"] == [[pytest.approx(a, abs=1e-7), pytest.approx(b, abs=1e-7)] for a, b in poly]
    (circle,) = plan["geoFence"]["circles"]
    assert circle["inclusion"] is False and circle["circle"]["radius"] == 25.5
    assert circle["circle"]["center"] == [pytest.approx(-35.3630, abs=1e-7), pytest.approx(149.1655, abs=1e-7)]
    assert plan["geoFence"]["breachReturn"] == [pytest.approx(-35.3632, abs=1e-7),
                                                pytest.approx(149.1652, abs=1e-7), 30.0]
    assert plan["rallyPoints"] == {"points": [[pytest.approx(a, abs=1e-7), pytest.approx(b, abs=1e-7), c]
                                              for a, b, c in rally], "version": 2}


def test_clear_all_set_current_and_refused_download_are_events(cli: Cli, tmp_path: Path) -> None:
    x = Exchange()
    x.heartbeats()
    clear = x.send("gcs", "MISSION_CLEAR_ALL", *VEH, 0)
    clear_ack = x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 0)
    x.send("veh", "MISSION_CURRENT", 0)
    setc = x.send("gcs", "MISSION_SET_CURRENT", *VEH, 2)
    x.send("veh", "MISSION_CURRENT", 0)  # streamed before the vehicle acted on it
    current = x.send("veh", "MISSION_CURRENT", 2)
    bad = x.send("gcs", "MISSION_SET_CURRENT", *VEH, 9)
    other = x.send("veh", "MISSION_CURRENT", 2, dt=0.5)
    x.wait(11.0)  # past the protocol timeout: MISSION_CURRENT never reported 9
    x.send("veh", "MISSION_CURRENT", 2)
    ask = x.send("gcs", "MISSION_REQUEST_LIST", *VEH, 1)
    deny = x.send("veh", "MISSION_ACK", *GCS, DENIED, 1)
    fence_clear = x.send("gcs", "MISSION_CLEAR_ALL", *VEH, 1)
    doc = cli.json("mission", x.tlog(tmp_path / "ops.tlog"))
    assert doc["transfers"] == []
    ev = doc["events"]
    assert [(e["kind"], e["frames"], e["result"]) for e in ev] == [
        ("clear-all", [clear, clear_ack], "MAV_MISSION_ACCEPTED"), ("set-current", [setc], None),
        ("set-current", [bad], None), ("request-list", [ask, deny], "MAV_MISSION_DENIED"),
        ("clear-all", [fence_clear], None)]
    assert (ev[1]["seq"], ev[1]["confirmed"], ev[1]["reported_seq"], ev[1]["reply_frame"]) == (2, True, 2, current)
    assert (ev[2]["seq"], ev[2]["confirmed"], ev[2]["reported_seq"], ev[2]["reply_frame"]) == (9, False, 2, other)
    assert ev[4]["mission_type"] == "MAV_MISSION_TYPE_FENCE" and "no MISSION_ACK" in ev[4]["text"]
    status, text, _ = cli("mission", str(tmp_path / "ops.tlog"))
    assert status == 0 and "Event 1: MISSION_CLEAR_ALL MAV_MISSION_TYPE_MISSION from 255/190 to 1/1: " \
                           "MISSION_ACK MAV_MISSION_ACCEPTED" in text


def test_plan_of_an_ardupilot_mission_takes_home_from_item_0(cli: Cli, tmp_path: Path) -> None:
    # ArduRover (HEARTBEAT type 10, autopilot 3): item 0 of a mission is home; QGroundControl shows it as
    # plannedHomePosition and numbers the other items from 1 (doJumpId = seq).
    x = Exchange()
    x.heartbeats(vehicle_type=10, autopilot=3)
    home = (-35.3632621, 149.1652374, 584.0)
    x.send("gcs", "MISSION_COUNT", *VEH, 4, 0)
    for s in range(4):
        x.send("veh", "MISSION_REQUEST", *GCS, s, 0)
        if s == 0:
            item_int(x, "gcs", VEH, 0, 16, *home, frame=0)
        else:
            item_int(x, "gcs", VEH, s, 16, *WAYPOINTS[s])
    x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 0)
    out = tmp_path / "ap.plan"
    status, _, err = cli("mission", x.tlog(tmp_path / "ap.tlog"), "--plan", str(out))
    assert status == 0 and err == ""
    mission = json.loads(out.read_text())["mission"]
    assert (mission["firmwareType"], mission["vehicleType"]) == (3, 10)
    assert mission["plannedHomePosition"] == [pytest.approx(home[0], abs=1e-7), pytest.approx(home[1], abs=1e-7), 584.0]
    assert [(i["doJumpId"], i["command"], i["frame"]) for i in mission["items"]] == [(1, 16, 3), (2, 16, 3), (3, 16, 3)]
    assert mission["items"][0]["params"][4:] == [pytest.approx(WAYPOINTS[1][0], abs=1e-7),
                                                 pytest.approx(WAYPOINTS[1][1], abs=1e-7), WAYPOINTS[1][2]]
    assert mission["items"][0]["AltitudeMode"] == 1  # relative: MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT)


def test_plan_of_an_incomplete_transfer_warns(cli: Cli, tmp_path: Path) -> None:
    x = Exchange()
    x.heartbeats(vehicle_type=1, autopilot=12)  # PX4 fixed wing
    x.send("gcs", "MISSION_COUNT", *VEH, 3, 0)
    for s in range(2):
        x.send("veh", "MISSION_REQUEST_INT", *GCS, s, 0)
        item_int(x, "gcs", VEH, s, 16, *WAYPOINTS[s])
    out = tmp_path / "part.plan"
    path = x.tlog(tmp_path / "part.tlog")
    status, _, err = cli("mission", path, "--plan", str(out))
    assert status == 0 and "warning: the exported mission (transfer 1) is incomplete: abandoned" in err
    doc = cli.json("mission", path, "--plan", str(out))
    assert doc["plan"]["mission_transfer"] == 1 and doc["plan"]["warnings"][0].startswith("the exported mission")
    mission = json.loads(out.read_text())["mission"]
    assert (mission["firmwareType"], mission["vehicleType"]) == (12, 1)
    assert [i["doJumpId"] for i in mission["items"]] == [1, 2]  # PX4: no home item, seq + 1


def test_the_copy_the_receiver_asked_for_is_the_item_and_late_frames_stay_late(cli: Cli, tmp_path: Path) -> None:
    # The vehicle asks for item 0 twice (the first copy did not reach it); the GCS answers the second request
    # with an edited item 0; a third copy of item 0 arrives after the vehicle asked for item 1 (it answers
    # nothing). After the ACK the GCS sends item 1 again and PX4, idle, ACKs it again: frames of the ended
    # transfer, not a new one.
    x = Exchange()
    x.heartbeats()
    edited = (WAYPOINTS[0][0] + 0.001, WAYPOINTS[0][1], WAYPOINTS[0][2])
    x.send("gcs", "MISSION_COUNT", *VEH, 2, 0)
    x.send("veh", "MISSION_REQUEST_INT", *GCS, 0, 0)
    item_int(x, "gcs", VEH, 0, 16, *WAYPOINTS[0])
    x.send("veh", "MISSION_REQUEST_INT", *GCS, 0, 0, dt=1.5)
    asked = item_int(x, "gcs", VEH, 0, 16, *edited)
    x.send("veh", "MISSION_REQUEST_INT", *GCS, 1, 0)
    stray = item_int(x, "gcs", VEH, 0, 16, *WAYPOINTS[0])
    item_int(x, "gcs", VEH, 1, 16, *WAYPOINTS[1])
    x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 0)
    x.wait(0.5)
    again = item_int(x, "gcs", VEH, 1, 16, *WAYPOINTS[1])
    reack = x.send("veh", "MISSION_ACK", *GCS, ACCEPTED, 0)
    doc = cli.json("mission", x.tlog(tmp_path / "copies.tlog"))
    (t,) = doc["transfers"]
    assert t["complete"] and doc["events"] == []
    zero = t["items"][0]
    assert zero["x"] == pytest.approx(edited[0], abs=1e-7) and zero["frames"][1:] == [asked, stray]
    assert (t["resent_items"], t["resent_changed"]) == ([0], [0])
    assert t["late_frames"] == [again, reack] and [a["role"] for a in t["acks"]] == ["final", "late"]


def test_a_count_of_65535_costs_what_its_items_cost(cli: Cli, tmp_path: Path) -> None:
    """Hostile: MISSION_COUNTs of 65,535 (the field's largest) with two items each. `missing` once listed
    every absent seq, worked out over all 65,535 at each use: 2,143 such transfers in a 300 KB tlog took
    `mission --json` 168 s and a JSON of millions of numbers. Runs of seqs now, from the items alone; the
    runs below follow from the items sent (5 and 7) and the count."""
    x = Exchange()
    for _ in range(50):
        x.send("gcs", "MISSION_COUNT", *VEH, 65535, 0)
        item_int(x, "gcs", VEH, 5, 16, *WAYPOINTS[0])
        item_int(x, "gcs", VEH, 7, 16, *WAYPOINTS[1])
        item_int(x, "gcs", VEH, 70000 % 65536, 16, *WAYPOINTS[2])  # seq 4464: inside the count too
    status, out, err = cli("mission", x.tlog(tmp_path / "big.tlog"), "--json")
    assert status == 0, err
    transfers = json.loads(out)["transfers"]
    assert len(transfers) == 50
    for t in transfers:
        assert t["missing"] == [[0, 4], [6, 6], [8, 4463], [4465, 65534]]
        assert t["missing_count"] == 65535 - 3
    assert len(out) < 50 * 8000  # each transfer's JSON: its items and four runs


def test_more_open_transfers_than_followed_give_up_the_newest_unanswered(cli: Cli, tmp_path: Path) -> None:
    """Hostile: a ground station starts uploads to 1,100 vehicles (sysid 1..250, compid 1..5) that nothing
    answers. Every mission frame is compared with every open transfer, so at most OPEN_MAX (1,024) stay
    open: each COUNT past them closes the newest unanswered transfer but itself as `evicted` (docs/security.md,
    "Bounds": what was open before the flood stays), so by hand transfers 1,024..1,099 (the 76 before the
    last) are evicted, the first 1,023 and the last closed at the capture's end; none is lost."""
    from mavscope.analysis.mission.model import OPEN_MAX

    x = Exchange()
    targets = [(1 + i % 250, 1 + i // 250) for i in range(OPEN_MAX + 76)]
    for t in targets:
        x.send("gcs", "MISSION_COUNT", *t, 3, 0, dt=0.0001)
    doc = cli.json("mission", x.tlog(tmp_path / "many.tlog"))
    assert [tuple(t["to"]) for t in doc["transfers"]] == targets
    assert [t["closed"] for t in doc["transfers"]] == ["end"] * (OPEN_MAX - 1) + ["evicted"] * 76 + ["end"]
    assert all(t["outcome"] == "abandoned" for t in doc["transfers"])
