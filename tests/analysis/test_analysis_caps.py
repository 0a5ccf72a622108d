"""The analyses' bounds under a flood (issue 35, item 1; docs/security.md, "Bounds"): what a bound gives up is
said (a `capacity` finding, which `audit` reports), and a flood of made-up ids cannot make the analyst lose the
genuine vehicle or command. One test per class of bound in the analyses:

- waiting for an answer (commands waiting for their ACK, TIMESYNC requests): the newest but the one just
  made is given up, so what waited before the flood is still answered;
- tables keyed by sender (vehicles, control, gnss senders, events): as many entries as there are (system,
  component) pairs, so they never fill: a flood past the old bound (4,096) still shows the vehicle;
- GNSS anomaly episodes (10 a sender): the least established sender's go first, said.

Every expected count is worked out by hand from the capture the test builds (comments say how); each test fails
under the old policy (oldest first, or the first N senders kept). Both engines give the same output.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis import command_log, gnss, timeline, vehicles
from tests.conftest import Cli
from tests.support.builders import vehicle_heartbeat_msg
from tests.support.flows import T0, Sender, command_long, write_tlog

PURE, NATIVE = {"MAVSCOPE_PURE": "1"}, {"MAVSCOPE_PURE": "0"}


def same_on_both_engines(cli: Cli, path: str, *commands: str) -> None:
    for command in commands:
        argv = (command, path, "--json")
        assert cli(*argv, environ=NATIVE) == cli(*argv, environ=PURE), command


def flood_senders(n: int) -> list[Sender]:
    """`n` made-up senders, none of them 1/1 (the vehicle) or 255/190 (the ground station)."""
    pairs = [(s, c) for s in range(2, 255) for c in range(256)]
    return [Sender(s, c) for s, c in pairs[:n]]


def test_a_command_flood_gives_up_its_own_commands_and_says_so(cli: Cli, tmp_path: Path) -> None:
    """An ARM from 255/190 to 1/1 (record 1), then 4,100 COMMAND_LONGs from made-up senders (records 2-4101),
    then the vehicle's ACK of the ARM (record 4102). PENDING_MAX is 4,096: the ARM and flood commands 1-4095
    wait; flood commands 4096-4100 (records 4097-4101) each give up the newest waiting but themselves, i.e.
    the flood command before them (records 4096-4100): 5 give-ups, said at the 1st, 2nd and 4th (records 4097,
    4098, 4100). The ACK answers the ARM (the old policy, oldest first, gave the ARM up as unanswered and
    made its ACK an orphan: `commands` showed the ARM UNANSWERED and `audit` said nothing)."""
    assert command_log.PENDING_MAX == 4096
    gcs, vehicle = Sender(255, 190), Sender(1, 1)
    entries = [(T0, gcs.pack(command_long(400, 1.0)))]
    entries += [(T0 + 0.001 * (i + 1), s.pack(command_long(400, 1.0))) for i, s in enumerate(flood_senders(4100))]
    entries.append((T0 + 5, vehicle.pack(v2.MAVLink_command_ack_message(400, 0, 0, 0, 255, 190))))
    path = write_tlog(tmp_path, entries)
    doc = cli.json("commands", path)
    arm = doc["commands"][0]
    assert (arm["frames"], arm["result"], arm["ack_frame"], arm["given_up"]) == ([1], "MAV_RESULT_ACCEPTED", 4102,
                                                                                 False)
    assert [c["frames"][0] for c in doc["commands"] if c["given_up"]] == [4096, 4097, 4098, 4099, 4100]
    assert doc["given_up"] == 5 and doc["unanswered"] == 4100 and doc["unmatched_acks"] == []
    assert [(f["code"], f["frames"]) for f in doc["findings"]] == [("capacity", [4097, 4098, 4100])]
    status, out, _ = cli("commands", path)
    assert "[warn] capacity: commands waiting for their ACK (at most 4,096): 5 given up" in out
    assert out.count("GIVEN UP") == 5
    status, out, _ = cli("audit", path, "--json")
    capacity = [f for f in json.loads(out)["findings"] if f["code"] == "capacity"]
    assert status == 1 and [f["frames"] for f in capacity] == [[4097, 4098, 4100]]
    assert "commands waiting for their ACK" in capacity[0]["message"]
    same_on_both_engines(cli, path, "commands", "audit", "events", "stats")


def test_a_timesync_flood_keeps_the_request_waiting_before_it(cli: Cli, tmp_path: Path) -> None:
    """A TIMESYNC request from 1/1 (record 1, ts1 = 1), 4,100 requests from made-up senders (records 2-4101,
    other ts1), then 255/190's answer to ts1 = 1 (record 4102) 0.5 s after the request. PENDING_REQUESTS is 4,096:
    as for commands above, 5 requests are given up, said at records 4097, 4098, 4100, and the genuine request
    is still answered: one TIMESYNC round trip of 1 with 255 of 500 ms (the old policy dropped it first)."""
    assert timeline.PENDING_REQUESTS == 4096
    gcs, vehicle = Sender(255, 190), Sender(1, 1)
    entries = [(T0, vehicle.pack(v2.MAVLink_timesync_message(0, 1)))]
    entries += [(T0 + 0.0001 * (i + 1), s.pack(v2.MAVLink_timesync_message(0, 1000 + i)))
                for i, s in enumerate(flood_senders(4100))]
    entries.append((T0 + 0.5, gcs.pack(v2.MAVLink_timesync_message(123_000_000_000, 1))))
    path = write_tlog(tmp_path, entries)
    doc = cli.json("timeline", path)
    assert [(f["code"], f["frames"]) for f in doc["findings"]] == [("capacity", [4097, 4098, 4100])]
    assert "TIMESYNC requests waiting for their answer (at most 4,096): 5 given up" in doc["findings"][0]["message"]
    trips = [r for s in doc["systems"] if s["sysid"] == 1 for r in s["round_trips"]]
    assert [(r["kind"], r["peer"], r["count"], r["frames"]) for r in trips] == [("TIMESYNC", 255, 1, [[1, 4102]])]
    assert trips[0]["min_ms"] == pytest.approx(500.0, abs=0.01)
    status, out, _ = cli("timeline", path)
    assert status == 0 and "[warn] capacity: TIMESYNC requests waiting" in out


def _hb(armed: bool) -> object:
    return vehicle_heartbeat_msg(armed, 5)  # a quadrotor, ArduPilot, LOITER


def _gps(sec: float, lat: int, sats: int = 12) -> object:
    return v2.MAVLink_gps_raw_int_message(round(sec * 1e6), 3, lat, 85455938, 500_000, 90, 0, 0, 0, sats)


def test_a_flood_of_senders_past_the_old_bound_does_not_hide_the_vehicle(cli: Cli, tmp_path: Path) -> None:
    """4,500 made-up senders (more than the 4,096 the analyses followed before) each send a vehicle HEARTBEAT
    (records 1-4500); then the vehicle 1/1 (disarmed) and the ground station 255/190 send a HEARTBEAT (4501,
    4502), the ground station arms it (4503), the vehicle's HEARTBEAT says armed (4504), a rogue 66/1 sends
    RC_CHANNELS_OVERRIDE to it (4505), the vehicle sends two GPS_RAW_INT 1 s apart 1.1 km apart without speed
    (4506, 4507). By hand: events show 1/1 as a vehicle and its arming at 4504; the control detector says 66
    sends control to armed vehicle 1 while 255 is in control (since 4503); gnss says a position jump of 1/1
    at 4507. With tables keyed by sender as large as the (system, component) pairs, nothing is given up: no
    capacity finding (4,500 stays below the events' listing, MAX_PER_KIND 5,000 a
    kind). Under the old bound every one of these was missing (the table was full of the flood)."""
    assert vehicles.MAX_SENDERS == 256 * 256
    entries = [(T0 + 0.0001 * i, s.pack(_hb(False))) for i, s in enumerate(flood_senders(4500))]
    vehicle, gcs, rogue = Sender(1, 1), Sender(255, 190), Sender(66, 1)
    t = T0 + 1
    entries += [(t, vehicle.pack(_hb(False))), (t + 0.1, gcs.pack(v2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))),
                (t + 0.2, gcs.pack(command_long(400, 1.0))), (t + 0.3, vehicle.pack(_hb(True))),
                (t + 0.4, rogue.pack(v2.MAVLink_rc_channels_override_message(1, 1, *([1500] * 8)))),
                (t + 0.5, vehicle.pack(_gps(10.0, 473977419))),
                (t + 1.5, vehicle.pack(_gps(11.0, 473977419 + 100_000)))]
    path = write_tlog(tmp_path, entries)
    doc = cli.json("events", path)
    mine = [(e["frame"], e["kind"]) for e in doc["events"]
            if e["from"] == [1, 1] and e["kind"] in ("vehicle", "arming")]
    assert mine == [(4501, "vehicle"), (4504, "arming")]
    found = {(f["code"], f["frames"][-1]): f["message"] for f in doc["findings"]}
    assert found[("second-gcs-control", 4505)].startswith("system 66 sends control to armed vehicle 1 while system "
                                                          "255 is in control (since frame 4503)")
    assert found[("gnss-position-jump", 4507)].startswith("GPS_RAW_INT of 1/1: 1 position jumps")
    status, out, _ = cli("audit", path, "--json")
    assert "capacity" not in {f["code"] for f in json.loads(out)["findings"]}
    same_on_both_engines(cli, path, "events", "stats", "audit")


def test_gnss_episodes_past_their_bound_give_up_the_least_established_senders(
        cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """MAX_EPISODES lowered to 4 (the native plan is built afresh with it). The vehicle 1/1 sends 40 steady
    GPS_RAW_INT (records 1-40); 7 made-up senders then send two fixes each, 1.1 km apart 1 s apart without
    speed: a position jump each (sender i's fixes at records 40 + 2i - 1 and 40 + 2i); then the vehicle jumps
    (record 55). By hand: senders 1-4's episodes fill the table (each of a sender with 2 frames: bit length 2);
    senders 5, 6, 7 (records 50, 52, 54) are as established: their episodes are given up (give-ups 1-3); the
    vehicle, with 41 frames (bit length 6), gives up the newest of the least established, sender 4's (give-up
    4). Said at the 1st, 2nd and 4th: records 50, 52, 55. Findings: jumps of senders 1-3 and of the vehicle
    (the old policy, the first kept, dropped the vehicle's). Both engines give the same output."""
    monkeypatch.setattr(gnss, "MAX_EPISODES", 4)
    vehicle = Sender(1, 1)
    entries = [(T0 + i, vehicle.pack(_gps(100.0 + i, 473977419))) for i in range(40)]
    flood = flood_senders(7)
    for i, s in enumerate(flood):
        entries += [(T0 + 40 + i, s.pack(_gps(5.0, 473977419))), (T0 + 40.5 + i, s.pack(_gps(6.0, 474077419)))]
    entries.append((T0 + 50, vehicle.pack(_gps(140.0, 474077419))))
    path = write_tlog(tmp_path, entries)
    doc = cli.json("stats", path, environ=PURE)
    jumps = sorted(f["frames"][-1] for f in doc["findings"] if f["code"] == "gnss-position-jump")
    assert jumps == [42, 44, 46, 55]
    capacity = [f for f in doc["findings"] if f["code"] == "capacity"]
    assert [f["frames"] for f in capacity] == [[50, 52, 55]]
    assert capacity[0]["message"].startswith("GNSS anomaly episodes (at most 4 (kind, sender, message) held): "
                                             "4 given up (4 episodes); the last said: GPS_RAW_INT "
                                             f"gnss-position-jump of {flood[3].mav.srcSystem}/"
                                             f"{flood[3].mav.srcComponent} (1 frame(s)) given up for")
    status, out, _ = cli("audit", path, "--json", environ=PURE)
    assert [f["frames"] for f in json.loads(out)["findings"] if f["code"] == "capacity"] == [[50, 52, 55]]
    same_on_both_engines(cli, path, "stats", "audit", "events")
