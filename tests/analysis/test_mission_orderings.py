"""The mission protocol as ground stations and vehicles speak it (issue 35 item 11): each ordering a real
ground station produces, run between simulated parties (tests/analysis/mission_sim.py) that follow the
MAVLink mission protocol's state machine (mavlink.io/en/services/mission.html) as ArduPilot's
MissionItemProtocol, Mission Planner (ExtLibs/ArduPilot/mav_mission.cs, MAVLinkInterface.SetWPTotal),
QGroundControl's PlanManager and MAVProxy's wp module (MAVProxy/modules/lib/mission_item_protocol.py) run it.

The expected answers are the simulated parties' own record: every upload the vehicle accepted (it sent
MISSION_ACK ACCEPTED after receiving its last item) must be a `complete` transfer from that GCS to that
vehicle, each it refused a `nack`, each MISSION_CLEAR_ALL it accepted a clear-all event, each download the
GCS finished a `complete` download; the .plan must hold what the vehicle holds at the end (`SimVehicle.held`),
or say it holds none. No accepted transfer may be called missing or unacknowledged.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.analysis.mission_sim import ACCEPTED, Link, SimGcs, SimVehicle
from tests.conftest import Cli

WP = [(-35.3632621 + i * 0.0001, 149.1652374 + i * 0.0002, 20.0 + i) for i in range(30)]
RESULTS = {0: "complete", 4: "nack", 14: "nack"}
TYPES = {0: "MAV_MISSION_TYPE_MISSION", 1: "MAV_MISSION_TYPE_FENCE", 2: "MAV_MISSION_TYPE_RALLY",
         255: "MAV_MISSION_TYPE_ALL"}


def heartbeats(link: Link, *parties: Any) -> None:
    for p in parties:
        if isinstance(p, SimVehicle):
            p.send("HEARTBEAT", 2, 12, 0, 0, 4, 3)  # a PX4 quadrotor: no home item in its missions
        else:
            p.send("HEARTBEAT", 6, 8, 0, 0, 4, 3)


def mission_planner_clear_then_count(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # Mission Planner, MAVLink 1 style: MISSION_CLEAR_ALL and MISSION_COUNT back to back, so the vehicle's
    # ACK of the clear comes after the COUNT; MISSION_REQUEST / MISSION_ITEM (floats), 8 items.
    v, g = SimVehicle(link, legacy=True), SimGcs(link, legacy=True)
    heartbeats(link, v, g)
    g.upload(v.addr, 0, WP[:8], clear_first=True)
    return [v], [g]


def legacy_upload_to_broadcast(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # A legacy upload to target 0/0, answered by system 10, whose requests and ACK address 0/0 too.
    v, g = SimVehicle(link, sysid=10, legacy=True, answer_broadcast=True), SimGcs(link, legacy=True)
    heartbeats(link, v, g)
    g.upload((0, 0), 0, WP[:2])
    return [v], [g]


def old_ardupilot_triple_clear_ack(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # ArduPilot 2.x acknowledged MISSION_CLEAR_ALL three times; the COUNT follows the clear at once.
    v, g = SimVehicle(link, clear_acks=3), SimGcs(link)
    heartbeats(link, v, g)
    g.upload(v.addr, 0, WP[:3])
    link.run()
    g.upload(v.addr, 0, WP[3:8], clear_first=True)
    return [v], [g]


def clear_by_empty_upload_and_clear_all(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # QGroundControl clears by uploading count 0; then fence and rally uploads, a MISSION_CLEAR_ALL of type
    # ALL (all three types).
    v, g = SimVehicle(link), SimGcs(link)
    heartbeats(link, v, g)
    g.upload(v.addr, 0, WP[:4])
    link.run()
    g.upload(v.addr, 0, [])
    link.run()
    g.upload(v.addr, 2, WP[10:12])
    link.run()
    g.send("MISSION_CLEAR_ALL", *v.addr, 255)
    return [v], [g]


def download_interleaved_with_upload(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # MAVProxy (255/0... here 254/1, asking 5 items at a time with MISSION_REQUEST) downloads the mission
    # while QGroundControl (255/190) uploads a fence to the same vehicle: two exchanges kept apart by
    # mission type and by who answers.
    v = SimVehicle(link, answer_broadcast=False)
    qgc, mavproxy = SimGcs(link), SimGcs(link, sysid=254, compid=1, legacy=True, window=5)
    heartbeats(link, v, qgc, mavproxy)
    qgc.upload(v.addr, 0, WP[:12])
    link.run()
    mavproxy.download(v.addr, 0)
    qgc.upload(v.addr, 1, WP[20:24])
    return [v], [qgc, mavproxy]


def two_vehicles_one_broadcast_count(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # A GCS uploads to target 0/0 with two vehicles on the link: both take the MISSION_COUNT and the
    # broadcast items, each requests and accepts them.
    a, b, g = SimVehicle(link, sysid=1), SimVehicle(link, sysid=2), SimGcs(link)
    heartbeats(link, a, b, g)
    g.upload((0, 0), 0, WP[:3])
    return [a, b], [g]


def second_gcs_denied_and_no_space(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # GCS B sends its MISSION_COUNT while GCS A's upload is in progress: the vehicle answers DENIED; then an
    # upload larger than the vehicle's storage: MAV_MISSION_NO_SPACE.
    v, a, b = SimVehicle(link, capacity=10), SimGcs(link), SimGcs(link, sysid=250, compid=250)
    heartbeats(link, v, a, b)
    a.upload(v.addr, 0, WP[:4])
    b.upload(v.addr, 0, WP[:2])
    link.run()
    a.upload(v.addr, 0, WP[:12])
    return [v], [a, b]


def lossy_link_rerequests(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # Items 2 and 5 are lost before the vehicle gets them (the capture, at the GCS, has them): the vehicle
    # asks again after its timeout and the GCS sends them again.
    v, g = SimVehicle(link), SimGcs(link)
    heartbeats(link, v, g)
    lost = {2, 5}

    def drop(party: Any, msg: Any) -> bool:
        if party is v and msg.get_type() == "MISSION_ITEM_INT" and msg.seq in lost:
            lost.discard(msg.seq)
            return True
        return False

    link.drop = drop
    g.upload(v.addr, 0, WP[:7])
    return [v], [g]


def partial_update(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # MAVProxy's `wp move 3`: after a 6-item upload, MISSION_WRITE_PARTIAL_LIST 3..3 and item 3 again.
    v, g = SimVehicle(link), SimGcs(link)
    heartbeats(link, v, g)
    g.upload(v.addr, 0, WP[:6])
    link.run()
    g.plans[0] = WP[:3] + [WP[20]] + WP[4:6]
    g.send("MISSION_WRITE_PARTIAL_LIST", *v.addr, 3, 3, 0)
    return [v], [g]


def px4_takes_a_count_to_the_mission_planner_component(link: Link) -> tuple[list[SimVehicle], list[SimGcs]]:
    # PX4's mission manager takes a message to component 190 (MAV_COMP_ID_MISSIONPLANNER) as its own
    # (CHECK_SYSID_COMPID_MISSION): a COUNT addressed to 1/190 is answered by the autopilot 1/1.
    v, g = SimVehicle(link, components=(190,)), SimGcs(link)
    heartbeats(link, v, g)
    g.upload((1, 190), 0, WP[:3])
    return [v], [g]


SCENARIOS: dict[str, Callable[[Link], tuple[list[SimVehicle], list[SimGcs]]]] = {
    f.__name__: f for f in (mission_planner_clear_then_count, legacy_upload_to_broadcast,
                            old_ardupilot_triple_clear_ack, clear_by_empty_upload_and_clear_all,
                            download_interleaved_with_upload, two_vehicles_one_broadcast_count,
                            second_gcs_denied_and_no_space, lossy_link_rerequests, partial_update,
                            px4_takes_a_count_to_the_mission_planner_component)}


def build(name: str, tmp_path: Path) -> tuple[str, list[SimVehicle], list[SimGcs]]:
    link = Link()
    vehicles, gcss = SCENARIOS[name](link)
    link.run()
    return link.tlog(tmp_path / f"{name}.tlog"), vehicles, gcss


def expected(vehicles: list[SimVehicle], gcss: list[SimGcs]) -> tuple[list[tuple], list[tuple]]:
    """The transfers and clears the parties' records say happened (sorted: the records are in the order
    each finished, mavscope's in the order each began)."""
    transfers, clears = [], []
    for v in vehicles:
        for entry in v.log:
            if entry[0] == "clear":
                clears.append(("clear-all", list(entry[1]), list(v.addr), TYPES[entry[2]], "MAV_MISSION_ACCEPTED"))
            else:
                _, gcs, mtype, count, result = entry
                transfers.append(("upload", list(gcs), list(v.addr), mtype, count, RESULTS[result]))
    for g in gcss:
        for vehicle, mtype, count in g.downloads:
            transfers.append(("download", list(vehicle), list(g.addr), mtype, count, "complete"))
    return sorted(transfers), sorted(clears)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_transfers_are_what_the_parties_did(name: str, tmp_path: Path, cli: Cli) -> None:
    path, vehicles, gcss = build(name, tmp_path)
    doc = cli.json("mission", path)
    want_t, want_c = expected(vehicles, gcss)
    got_t = sorted((t["direction"], t["from"], t["to"], t["mission_type_id"],
                    t["partial"][1] + 1 if t["partial"] else t["count"], t["outcome"]) for t in doc["transfers"])
    assert got_t == want_t
    got_c = sorted((e["kind"], e["from"], e["to"], e["mission_type"], e["result"]) for e in doc["events"])
    assert got_c == want_c  # nothing else: no unmatched ACK, no orphan frame
    for t in doc["transfers"]:  # every transfer the vehicle accepted has its items in the capture (taken at the GCS)
        if t["result"] == "MAV_MISSION_ACCEPTED":
            assert t["outcome"] == "complete" and t["missing"] == []


def test_mission_planner_ack_of_the_clear_is_the_clears(tmp_path: Path, cli: Cli) -> None:
    # The record numbers: 1-2 HEARTBEATs, 3 CLEAR_ALL, 4 COUNT, 5 the vehicle's ACK (of the clear: it
    # handled the clear first), 6.. MISSION_REQUEST / MISSION_ITEM pairs, then the final ACK.
    path, (v,), _ = build("mission_planner_clear_then_count", tmp_path)
    doc = cli.json("mission", path)
    (clear,) = doc["events"]
    assert (clear["frames"], clear["ack_frame"]) == ([3, 5], 5)
    (t,) = doc["transfers"]
    assert t["frames"][0] == 4 and 5 not in t["frames"] and t["acks"][-1]["role"] == "final"
    assert [i["message"] for i in t["items"]] == ["MISSION_ITEM"] * 8 and t["requests"] == 8


def test_repeated_clear_acks_stay_with_the_clear(tmp_path: Path, cli: Cli) -> None:
    path, (v,), _ = build("old_ardupilot_triple_clear_ack", tmp_path)
    (clear,) = cli.json("mission", path)["events"]
    assert len(clear["repeated_ack_frames"]) == v.clear_acks - 1 == 2
    assert "2 more time(s)" in clear["text"]


def test_broadcast_upload_names_who_answered(tmp_path: Path, cli: Cli) -> None:
    path, (v,), _ = build("legacy_upload_to_broadcast", tmp_path)
    (t,) = cli.json("mission", path)["transfers"]
    assert (t["to"], t["addressed_to"]) == ([10, 1], [0, 0])
    status, out, _ = cli("mission", path)
    assert status == 0 and "to 10/1 (addressed to 0/0), 2 items, complete" in out


def plan_of(cli: Cli, path: str, tmp_path: Path, *extra: str) -> tuple[dict, dict, str]:
    out = tmp_path / "x.plan"
    status, _, err = cli("mission", path, "--plan", str(out), *extra)
    assert status == 0, err
    return json.loads(out.read_text()), cli.json("mission", path, "--plan", str(out), *extra)["plan"], err


@pytest.mark.parametrize("name", ["mission_planner_clear_then_count", "partial_update", "lossy_link_rerequests",
                                  "download_interleaved_with_upload"])
def test_plan_holds_what_the_vehicle_holds(name: str, tmp_path: Path, cli: Cli) -> None:
    path, (v, *_), _ = build(name, tmp_path)
    plan, info, _ = plan_of(cli, path, tmp_path)
    held = v.held[0]
    items = plan["mission"]["items"]
    assert [i["doJumpId"] for i in items] == [s + 1 for s in sorted(held)]  # PX4 numbering: seq + 1
    for item, seq in zip(items, sorted(held)):
        m = held[seq]
        lat = m.x if m.get_type() == "MISSION_ITEM" else m.x / 1e7
        assert item["params"][4] == pytest.approx(lat, abs=5e-6)  # MISSION_ITEM: float32 on the wire
    assert info["cleared"] == {}


def test_after_an_empty_upload_and_clear_all_the_vehicle_holds_nothing(tmp_path: Path, cli: Cli) -> None:
    # The vehicle's record: mission of 4 items, emptied by the count-0 upload; rally of 2; then
    # MISSION_CLEAR_ALL MAV_MISSION_TYPE_ALL empties all three: the last change of each type is that clear.
    path, (v,), _ = build("clear_by_empty_upload_and_clear_all", tmp_path)
    assert v.held == {0: {}, 1: {}, 2: {}}
    assert [(e[0], e[2]) for e in v.log] == [("upload", 0), ("upload", 0), ("upload", 2), ("clear", 255)]
    plan, info, err = plan_of(cli, path, tmp_path)
    assert plan["mission"]["items"] == [] and plan["rallyPoints"]["points"] == []
    assert info["mission_transfer"] is None and info["rally_transfer"] is None
    doc = cli.json("mission", path)
    clear_event = 1 + [e["kind"] for e in doc["events"]].index("clear-all")
    # the mission: emptied by transfer 2 (count 0), then by the clear; the 4-item upload, transfer 1, is history
    assert info["cleared"]["mission"]["how"] == "clear-all" and info["cleared"]["mission"]["event"] == clear_event
    assert info["cleared"]["mission"]["history"] == [1] and info["cleared"]["fence"]["history"] == []
    assert info["cleared"]["rally"]["how"] == "clear-all" and info["cleared"]["rally"]["event"] == clear_event
    assert info["cleared"]["rally"]["history"] == [3]
    assert "holds no mission since frame" in err and "--plan-transfer 1" in err
    history, info, _ = plan_of(cli, path, tmp_path, "--plan-transfer", "1")
    assert len(history["mission"]["items"]) == 4 and info["mission_transfer"] == 1
    status, out, _ = cli("track", path, "--json")
    summary = json.loads(out)
    assert summary["mission_transfer"] is None and summary["history_mission_transfer"] == 1
    assert summary["cleared"]["mission"]["event"] == clear_event


def test_an_empty_upload_alone_clears_the_mission(tmp_path: Path, cli: Cli) -> None:
    # An accepted upload of count 0 after a 4-item one (the vehicle's record: upload 4, upload 0).
    link = Link()
    v, g = SimVehicle(link), SimGcs(link)
    heartbeats(link, v, g)
    g.upload(v.addr, 0, WP[:4])
    link.run()
    g.upload(v.addr, 0, [])
    link.run()
    assert [(e[0], e[3], e[4]) for e in v.log] == [("upload", 4, ACCEPTED), ("upload", 0, ACCEPTED)]
    _, info, err = plan_of(cli, link.tlog(tmp_path / "empty.tlog"), tmp_path)
    assert info["cleared"]["mission"]["how"] == "empty-upload" and info["cleared"]["mission"]["transfer"] == 2
    assert info["cleared"]["mission"]["history"] == [1] and "holds no mission since frame" in err


def test_every_ordering_is_the_same_on_both_engines(tmp_path: Path, cli: Cli) -> None:
    for name in sorted(SCENARIOS):
        path, _, _ = build(name, tmp_path)
        for argv in (["mission", path], ["mission", path, "--json"],
                     ["mission", path, "--plan", str(tmp_path / "p.plan")], ["track", path, "--json"],
                     ["track", path, "--geojson", "-"]):
            native = cli(*argv, environ={})
            plan = (tmp_path / "p.plan").read_text() if "--plan" in argv else ""
            pure = cli(*argv, environ={"MAVSCOPE_PURE": "1"})
            assert (native.status, native.out, native.err) == (pure.status, pure.out, pure.err), (name, argv)
            if plan:
                assert (tmp_path / "p.plan").read_text() == plan
