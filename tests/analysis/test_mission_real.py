"""`mavscope mission` on real ArduPilot, PX4, Mission Planner and QGroundControl traffic
(../shared/real-captures, PROVENANCE.md there), against answers derived without mavscope.

Two independent sources:
- EXPECTED below is written out from a derivation with pymavlink alone (a state machine over the decoded
  frames: a transfer opens at MISSION_COUNT, is a download when the receiver sent MISSION_REQUEST_LIST or
  the sender is a vehicle by HEARTBEAT, and closes at MISSION_ACK ACCEPTED from the receiver or any ACK from
  the sender), to be read with the captures; `test_expected_is_the_derivation` runs that derivation again
  (tests/support/real_truth.py, `mission_transfers`) and holds EXPECTED to it. Where mavscope's grouping
  deliberately differs, the comment says why.
- Items, coordinates, resent items, MISSION_SET_CURRENT answers and the .plan's HEARTBEAT numbers and home
  are derived at test time from the frames pymavlink decodes (tests/support/pymavlink_reader.py).
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import ROOT, Cli
from tests.support.pymavlink_reader import Msg, read

# (mission_type, direction, from, to, count, outcome, final MISSION_ACK result or None)
# outcome: "complete" = the final MISSION_ACK MAV_MISSION_ACCEPTED from the receiver, no item missing;
# "unacknowledged" = no final ACK, every item received; "cancelled" = an ACK from the sender.
G250, G255, V = [250, 250], [255, 190], [1, 1]
OK = "MAV_MISSION_ACCEPTED"
EXPECTED: dict[str, list[tuple[int, str, list[int], list[int], int, str, str | None]]] = {
    # Mission Planner downloads mission (4 items), fence and rally (0), each closed by MP's ACK; later MP
    # uploads count 0 for all three types (a clear), ACKed by ArduPlane.
    "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog": [
        (0, "download", V, G255, 4, "complete", OK), (1, "download", V, G255, 0, "complete", OK),
        (2, "download", V, G255, 0, "complete", OK), (0, "upload", G255, V, 0, "complete", OK),
        (1, "upload", G255, V, 0, "complete", OK), (2, "upload", G255, V, 0, "complete", OK)],
    # ArduPilot autotest GCS 250/250 and ArduRover: empty fence/mission/rally uploads, a 4-item upload and
    # its download, empty uploads, a 19-item upload and its download, empty uploads. The autotest GCS sends
    # no MISSION_ACK after a download: all items arrive, nothing acknowledges them.
    "ap_rover_mission_fence_rally_params.tlog": [
        (1, "upload", G250, V, 0, "complete", OK), (0, "upload", G250, V, 0, "complete", OK),
        (2, "upload", G250, V, 0, "complete", OK), (0, "upload", G250, V, 4, "complete", OK),
        (0, "download", V, G250, 4, "unacknowledged", None), (1, "upload", G250, V, 0, "complete", OK),
        (0, "upload", G250, V, 0, "complete", OK), (2, "upload", G250, V, 0, "complete", OK),
        (0, "upload", G250, V, 19, "complete", OK), (0, "download", V, G250, 19, "unacknowledged", None),
        (1, "upload", G250, V, 0, "complete", OK), (0, "upload", G250, V, 0, "complete", OK),
        (2, "upload", G250, V, 0, "complete", OK)],
    # QGroundControl downloads mission and fence from ArduSub, both empty.
    "ardusub_log_tools_small.tlog": [
        (0, "download", V, G255, 0, "complete", OK), (1, "download", V, G255, 0, "complete", OK)],
    # PX4 (a vehicle by HEARTBEAT) sends MISSION_COUNT 0 to 1/240 twice; 1/240 sends nothing in the capture.
    # the derivation lists one transfer with the second COUNT as a retry (it has no time limit); the two
    # COUNTs are 237.23 s apart (its count_frames times 1497166782.0072 and 1497167019.238484), far beyond
    # any party's protocol timeout (PX4 5 s, ArduPilot 8 s), so mavscope reports two downloads.
    "px4_2018_params_offboard.tlog": [
        (0, "download", V, [1, 240], 0, "unacknowledged", None),
        (0, "download", V, [1, 240], 0, "unacknowledged", None)],
    # One direction of a PX4 fixed-wing download: MISSION_COUNT 125 to 1/2, 145 MISSION_ITEM_INT covering
    # items 0..92, then the vehicle's own MISSION_ACK MAV_MISSION_ERROR (the derivation: an ACK from the sender).
    "px4_fw_mission_download_raw.bin": [
        (0, "download", V, [1, 2], 125, "cancelled", "MAV_MISSION_ERROR")],
}
MISSING = {("px4_fw_mission_download_raw.bin", 0): list(range(93, 125))}  # the derivation's missing items
SPLIT = {"px4_2018_params_offboard.tlog"}  # (above: one derived transfer whose COUNTs are minutes apart)


@pytest.fixture(scope="module")
def docs(real_captures: Path) -> dict[str, dict[str, Any]]:
    cli = Cli()
    return {name: cli.json("mission", str(real_captures / name)) for name in EXPECTED}


@pytest.fixture(scope="module")
def frames(real_captures: Path) -> dict[str, list[Msg]]:
    return {name: read(real_captures / name) for name in EXPECTED}


def segments(msgs: list[Msg]) -> list[dict[str, Any]]:
    """The MISSION_COUNTs in order, each with the MISSION_ITEM_INT copies its sender sent to its target for
    that mission type until the next MISSION_COUNT between them."""
    out: list[dict[str, Any]] = []
    current: dict[tuple[tuple[int, int], tuple[int, int], int], dict[str, Any]] = {}
    for m in msgs:
        if m.name not in ("MISSION_COUNT", "MISSION_ITEM_INT"):
            continue
        key = (m.src, (m.msg.target_system, m.msg.target_component), m.msg.mission_type)
        if m.name == "MISSION_COUNT":
            current[key] = {"key": key, "count": m.msg.count, "items": defaultdict(list)}
            out.append(current[key])
        elif key in current:
            current[key]["items"][m.msg.seq].append(m.msg)
    return out


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_expected_is_the_derivation(name: str, frames: dict[str, list[Msg]]) -> None:
    from pymavlink.dialects.v20 import all as mavlink

    from tests.support.real_truth import mission_transfers

    results = mavlink.enums["MAV_MISSION_RESULT"]
    rows = []
    for t in mission_transfers(frames[name]):
        ack = t["final_ack"]
        if ack is None:
            outcome = "unacknowledged" if not t["missing"] else "incomplete"
        elif ack["from"] == "sender":
            outcome = "cancelled"
        else:
            outcome = "complete" if ack["result"] == 0 and not t["missing"] else "failed"
        row = (t["mission_type"], t["direction"], list(t["from"]), list(t["to"]), t["count"], outcome,
               None if ack is None else results[ack["result"]].name)
        if name in SPLIT:  # each COUNT its own transfer: the retries are minutes apart
            times = t["count_times"]
            assert len(times) == 2 and times[1] - times[0] > 200
            rows += [row] * len(times)
        else:
            assert len(t["count_times"]) == 1
            rows.append(row)
        if t["missing"]:
            assert MISSING[(name, len(rows) - 1)] == t["missing"]
    assert rows == EXPECTED[name]
    assert len([k for k in MISSING if k[0] == name]) == sum(bool(t["missing"]) for t in mission_transfers(frames[name]))


def degrees(msg: Any) -> tuple[float, float]:
    """MISSION_ITEM_INT x/y in degrees (global frames) or as sent (MAV_FRAME_MISSION, 2)."""
    return (msg.x, msg.y) if msg.frame == 2 else (msg.x / 1e7, msg.y / 1e7)


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_transfers_match_the_independent_derivation(name: str, docs: dict[str, dict[str, Any]]) -> None:
    got = docs[name]["transfers"]
    want = EXPECTED[name]
    assert [(t["mission_type_id"], t["direction"], t["from"], t["to"], t["count"], t["outcome"], t["result"])
            for t in got] == want
    for i, t in enumerate(got):
        want = MISSING.get((name, i), [])
        assert [s for a, b in t["missing"] for s in range(a, b + 1)] == want and t["missing_count"] == len(want)
        assert t["complete"] is (t["outcome"] == "complete")
        final = [a for a in t["acks"] if a["role"] == "final"]
        if final and final[-1]["result"] == OK and final[-1]["from"] == t["to"]:  # the receiver accepted it
            assert t["outcome"] == "complete"  # never "missing" or "unacknowledged" (every item is here)
    # no false alarm: no duplicate, no ACK without its exchange, no frame outside a transfer
    assert docs[name]["duplicates"] == 0
    assert [e for e in docs[name]["events"] if e["kind"] in ("unmatched-ack", "orphan", "request-list")] == []


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_items_and_coordinates_match_pymavlink(name: str, docs: dict[str, dict[str, Any]],
                                               frames: dict[str, list[Msg]]) -> None:
    segs = segments(frames[name])
    got = docs[name]["transfers"]
    assert len(segs) == len(got)
    for t, seg in zip(got, segs):
        src, tgt, mtype = seg["key"]
        assert (t["from"], t["to"], t["mission_type_id"], t["count"]) == (list(src), list(tgt), mtype, seg["count"])
        assert [i["seq"] for i in t["items"]] == sorted(seg["items"])
        assert t["resent_items"] == sorted(s for s, copies in seg["items"].items() if len(copies) > 1)
        assert t["resent_changed"] == []  # every copy of an item is the same (checked below)
        assert sum(len(i["frames"]) for i in t["items"]) == sum(len(c) for c in seg["items"].values())
        for item in t["items"]:
            copies = seg["items"][item["seq"]]
            first = copies[0]
            # every copy of an item carries the same content in these captures, so any copy is the item
            assert all((c.command, c.frame, c.x, c.y, c.z) == (first.command, first.frame, first.x, first.y, first.z)
                       for c in copies)
            assert (item["command_id"], item["frame_id"]) == (first.command, first.frame)
            lat, lon = degrees(first)
            assert item["x"] == pytest.approx(lat, abs=1e-9) and item["y"] == pytest.approx(lon, abs=1e-9)
            assert item["z"] is None if math.isnan(first.z) else item["z"] == pytest.approx(first.z)  # NaN: null


def test_rover_item_0_is_home_as_the_vehicle_reports_it(docs: dict[str, dict[str, Any]],
                                                        frames: dict[str, list[Msg]]) -> None:
    # The vehicle replaces the uploaded item 0 with its home: item 0 of each upload and download, as
    # pymavlink decodes it (test_items_and_coordinates_match_pymavlink holds the items to its frames).
    got = docs["ap_rover_mission_fence_rally_params.tlog"]["transfers"]
    home = [(t["direction"], t["items"][0]["x"], t["items"][0]["y"]) for t in got if t["items"]]
    assert home == [("upload", 40.071377, -105.22979), ("download", 40.0714771, -105.229489),
                    ("upload", 40.071289, -105.230057), ("download", 40.0714469, -105.2294918)]
    zeros = [seg["items"][0][0] for seg in segments(frames["ap_rover_mission_fence_rally_params.tlog"]) if seg["count"]]
    assert [(z.x / 1e7, z.y / 1e7) for z in zeros] == [(x, y) for _, x, y in home]


def test_rover_set_current_answered_by_mission_current(docs: dict[str, dict[str, Any]],
                                                      frames: dict[str, list[Msg]]) -> None:
    # 6 MISSION_SET_CURRENT seq 0 from 250/250 to 1/1, no MISSION_CLEAR_ALL. Whether MISSION_CURRENT from
    # system 1 then reported the seq asked for (before the next MISSION_SET_CURRENT) is read from
    # pymavlink's frames here.
    msgs = frames["ap_rover_mission_fence_rally_params.tlog"]
    assert [(m.src, m.msg.target_system) for m in msgs if m.name == "MISSION_SET_CURRENT"] == [((250, 250), 1)] * 6
    assert not any(m.name == "MISSION_CLEAR_ALL" for m in msgs)
    asked = [i for i, m in enumerate(msgs) if m.name == "MISSION_SET_CURRENT"]
    want = []
    for n, i in enumerate(asked):
        stop = asked[n + 1] if n + 1 < len(asked) else len(msgs)
        reports = [m.msg.seq for m in msgs[i:stop] if m.name == "MISSION_CURRENT" and m.src[0] == 1]
        seq = msgs[i].msg.seq
        want.append((seq, True if seq in reports else (False if reports else None)))
    assert want == [(0, True), (0, True), (0, False), (0, False), (0, True), (0, None)]  # as derived, for reading
    events = docs["ap_rover_mission_fence_rally_params.tlog"]["events"]
    assert [(e["kind"], e["from"], e["to"]) for e in events] == [("set-current", G250, V)] * 6
    assert [(e["seq"], e["confirmed"]) for e in events] == want


def _heartbeat(msgs: list[Msg], src: tuple[int, int]) -> tuple[int, int]:
    last = [m.msg for m in msgs if m.name == "HEARTBEAT" and m.src == src][-1]
    return last.autopilot, last.type


@pytest.mark.parametrize(("name", "exported"), [
    ("ap_rover_mission_fence_rally_params.tlog", 9),  # the 19-item upload (since emptied: history, on request)
    ("ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog", 1),  # the 4-item download (since emptied, likewise)
])
def test_plan_of_an_ardupilot_capture(name: str, exported: int, real_captures: Path, tmp_path: Path,
                                      frames: dict[str, list[Msg]], cli: Cli) -> None:
    out = tmp_path / "real.plan"
    doc = cli.json("mission", str(real_captures / name), "--plan", str(out), "--plan-transfer", str(exported))
    plan = json.loads(out.read_text())
    msgs = frames[name]
    seg = segments(msgs)[exported - 1]
    assert doc["plan"]["mission_transfer"] == exported
    assert set(doc["plan"]) == {"file", "mission_transfer", "fence_transfer", "rally_transfer", "vehicle",
                                "cleared", "firmwareType", "vehicleType", "home_source",
                                "warnings"}  # as docs/analysis.md lists them
    mission = plan["mission"]
    # the vehicle's last HEARTBEAT: ArduPilot (MAV_AUTOPILOT_ARDUPILOTMEGA 3), its MAV_TYPE
    assert (mission["firmwareType"], mission["vehicleType"]) == _heartbeat(msgs, (1, 1))
    assert mission["firmwareType"] == 3
    zero = seg["items"][0][0]
    if zero.x or zero.y:  # item 0 is home
        assert mission["plannedHomePosition"] == [zero.x / 1e7, zero.y / 1e7, pytest.approx(zero.z)]
        assert doc["plan"]["home_source"] == "mission item 0 (ArduPilot home)"
    else:  # home was not set when the mission was read: the capture's last HOME_POSITION
        hp = [m.msg for m in msgs if m.name == "HOME_POSITION" and m.src[0] == 1][-1]
        assert mission["plannedHomePosition"] == [hp.latitude / 1e7, hp.longitude / 1e7, hp.altitude / 1000]
        assert any("item 0" in w for w in doc["plan"]["warnings"])
    items = mission["items"]
    assert [i["doJumpId"] for i in items] == list(range(1, seg["count"]))
    for item, seq in zip(items, range(1, seg["count"])):
        m = seg["items"][seq][0]
        assert item["command"] == m.command and item["autoContinue"] == bool(m.autocontinue)
        lat, lon = degrees(m)
        assert item["params"][4:6] == [pytest.approx(lat, abs=1e-9), pytest.approx(lon, abs=1e-9)]
        assert item["params"][6] == pytest.approx(m.z)
    assert plan["geoFence"] == {"circles": [], "polygons": [], "version": 2}  # every fence transfer is empty
    assert plan["rallyPoints"] == {"points": [], "version": 2}


def last_accepted_uploads(msgs: list[Msg]) -> dict[int, tuple[int, int, float]]:
    """Per mission type, the last upload the vehicle (1/1) accepted, by the mission protocol's rules
    (mavlink.io/en/services/mission.html): a MISSION_COUNT from another system to system 1 (or 0) opens an
    upload; the vehicle's MISSION_ACK of that type, MAV_MISSION_ACCEPTED, to that system, before the next
    MISSION_COUNT of the type, accepts it (at once for count 0: the spec's clear by empty upload). Gives
    (count, the COUNT's number among the capture's MISSION_COUNTs from 1, the ACK's time)."""
    out: dict[int, tuple[int, int, float]] = {}
    counts = 0
    uploading: dict[int, tuple[int, tuple[int, int], int]] = {}  # type -> (count, sender, number)
    for m in msgs:
        mtype = getattr(m.msg, "mission_type", 0) or 0
        if m.name == "MISSION_COUNT":
            counts += 1
            if m.src[0] != 1 and m.msg.target_system in (0, 1):
                uploading[mtype] = (m.msg.count, m.src, counts)
            else:
                uploading.pop(mtype, None)
        elif m.name == "MISSION_ACK" and m.src == (1, 1) and m.msg.type == 0 and mtype in uploading:
            count, sender, number = uploading[mtype]
            if m.msg.target_system in (0, sender[0]):
                out[mtype] = (count, number, m.time)
                del uploading[mtype]
    return out


@pytest.mark.parametrize("name", ["ap_rover_mission_fence_rally_params.tlog",
                                  "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog"])
def test_after_the_last_empty_upload_the_vehicle_holds_no_mission(name: str, real_captures: Path, tmp_path: Path,
                                                                   frames: dict[str, list[Msg]], cli: Cli) -> None:
    # Both captures end with accepted uploads of 0 items for mission, fence and rally (derived below): the
    # plan and the track must say the vehicle holds none since then, the earlier mission kept as history.
    last = last_accepted_uploads(frames[name])
    assert sorted(last) == [0, 1, 2] and all(count == 0 for count, _, _ in last.values())
    out = tmp_path / "now.plan"
    path = str(real_captures / name)
    status, _, err = cli("mission", path, "--plan", str(out))
    assert status == 0 and "holds no mission since frame" in err
    plan = json.loads(out.read_text())
    assert plan["mission"]["items"] == [] and plan["rallyPoints"]["points"] == []
    info = cli.json("mission", path, "--plan", str(out))["plan"]
    assert info["mission_transfer"] is None and info["vehicle"] == [1, 1]
    for mtype, what in ((0, "mission"), (1, "fence"), (2, "rally")):
        count, number, when = last[mtype]
        c = info["cleared"][what]
        assert (c["how"], c["transfer"]) == ("empty-upload", number) and c["at"] == pytest.approx(when, abs=1e-6)
    transfers = cli.json("mission", path)["transfers"]
    items = [n for n, t in enumerate(transfers, 1) if t["items"] and t["mission_type_id"] == 0]
    assert info["cleared"]["mission"]["history"] == items and items  # the transfers with items, all before
    summary = cli.json("track", path)
    assert summary["mission_transfer"] is None and summary["history_mission_transfer"] == items[-1]


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_both_engines_agree_on_real_captures(name: str, real_captures: Path, tmp_path: Path, cli: Cli) -> None:
    path = str(real_captures / name)
    runs = [["mission", path], ["mission", path, "--json"], ["track", path, "--json"]]
    if name.startswith("ap_") or name.startswith("px4_fw"):  # the captures with items: a plan to write
        runs.append(["mission", path, "--plan", str(tmp_path / "p.plan")])
    for argv in runs:
        native = cli(*argv, environ={})
        plan = (tmp_path / "p.plan").read_text() if "--plan" in argv else ""
        pure = cli(*argv, environ={"MAVSCOPE_PURE": "1"})
        assert (native.status, native.out, native.err) == (pure.status, pure.out, pure.err), argv
        assert plan == ((tmp_path / "p.plan").read_text() if "--plan" in argv else "")


def test_plan_of_an_incomplete_px4_download_warns(real_captures: Path, tmp_path: Path, cli: Cli,
                                                  frames: dict[str, list[Msg]]) -> None:
    out = tmp_path / "px4.plan"
    status, _, err = cli("mission", str(real_captures / "px4_fw_mission_download_raw.bin"), "--plan", str(out))
    assert status == 0 and "the exported mission (transfer 1) is incomplete: cancelled by the sender 1/1" in err
    mission = json.loads(out.read_text())["mission"]
    assert (mission["firmwareType"], mission["vehicleType"]) == _heartbeat(frames["px4_fw_mission_download_raw.bin"],
                                                                           (1, 1)) == (12, 1)
    assert [i["doJumpId"] for i in mission["items"]] == list(range(1, 94))  # items 0..92, no home item on PX4


def test_json_keys_are_documented(docs: dict[str, dict[str, Any]]) -> None:
    text = (ROOT / "docs" / "analysis.md").read_text()
    section = text[text.index("## `mavscope mission"):text.index("## `mavscope commands")]
    doc = docs["ap_rover_mission_fence_rally_params.tlog"]
    objects = [doc, doc["transfers"][3], doc["transfers"][3]["items"][0], doc["transfers"][3]["acks"][0],
               doc["events"][0]]
    keys = {k for o in objects for k in o}
    assert {k for k in keys if f"`{k}`" not in section} == set()
