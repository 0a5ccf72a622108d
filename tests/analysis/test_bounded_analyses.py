"""Bounds of the analyses under a hostile flood (issue 35, item 1; docs/security.md, "Bounds"): what the analyst
needs (a large bad-CRC burst, the vehicle's arming and the ARM command, an established mission upload) is
still shown, and what the bound gave up is said as a `capacity` finding that `audit` (and the analysis's own
command) reports. Every expected answer is worked out by hand from the flood the test builds (comments say
how); each test fails under the old policy (the first N listed, the oldest transfer closed, an unbounded list).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mavscope.analysis import expert
from tests.support import flows
from tests.support.builders import heartbeat_msg, vehicle_heartbeat_msg

ENGINES = ({"MAVSCOPE_PURE": "0"}, {"MAVSCOPE_PURE": "1"})


def bad_crc(frame: bytes, k: int) -> bytes:
    """`frame` with its CRC's low byte xored with `k` (1..255): a bad CRC, each `k` fitting another CRC_EXTRA,
    so no (sender, id, CRC_EXTRA) group reaches a dialect mismatch's 5 frames."""
    return frame[:-2] + bytes((frame[-2] ^ k, frame[-1]))


def findings(cli, *argv: object) -> dict[str, list[dict]]:  # type: ignore[no-untyped-def]
    status, out, err = cli(*argv, "--json")
    assert status in (0, 1), err
    got: dict[str, list[dict]] = {}
    for f in json.loads(out)["findings"]:
        got.setdefault(f["code"], []).append(f)
    return got


def test_a_flood_of_small_bad_crc_bursts_keeps_the_large_one(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """A burst of 10 bad-CRC HEARTBEATs 0.1 s apart (records 1-10), then 6 bursts of 3 (0.1 s apart, 2 s between
    bursts: records 11-13, 14-16, ..., 26-28). With 3 bursts listed at most: the large one and the first two
    small ones fit; each later small one is the smallest and newest when it closes, so it goes itself (4
    give-ups, 12 frames), said at the 1st, 2nd and 4th: the bursts from records 17, 20 and 26. `stats` lists
    the large burst; `audit` (which lists no burst: not a security finding) reports the give-up."""
    monkeypatch.setattr(expert, "MAX_BURSTS", 3)
    gcs = flows.Sender(1, 1)
    entries = [(flows.T0 + i * 0.1, bad_crc(gcs.pack(flows.heartbeat()), 1 + i)) for i in range(10)]
    for b in range(6):
        entries += [(flows.T0 + 10 + b * 2 + j * 0.1, bad_crc(gcs.pack(flows.heartbeat()), 20 + 3 * b + j))
                    for j in range(3)]
    path = flows.write_tlog(tmp_path, entries)
    for environ in ENGINES:
        cli.environ = environ
        stats = findings(cli, "stats", path)
        assert [f["frames"] for f in stats["bad-crc-burst"]] == [list(range(1, 11)), [11, 12, 13], [14, 15, 16]]
        assert "dialect-mismatch" not in stats
        audit = findings(cli, "audit", path)
        (cap,) = audit["capacity"]
        assert cap["frames"] == [17, 20, 26]
        assert "4 given up (12 frames)" in cap["message"]
        assert stats["capacity"] == audit["capacity"]


def _hb(armed: bool, gcs: bool = False) -> object:
    if gcs:
        return heartbeat_msg(6, 8)
    return vehicle_heartbeat_msg(armed, base_mode=81)  # a quadrotor, ArduPilot, STABILIZE (base 81, armed 209)


def test_a_flood_of_made_up_vehicles_keeps_the_vehicles_arming_and_the_arm_command(  # type: ignore[no-untyped-def]
        cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The events' listing with 2 first and 2 last events per (kind, sender), 6 events listed in all and 4
    STATUSTEXT/link events. Built:
      1-20 the vehicle 1/1 HEARTBEAT disarmed (its `vehicle` event at 1); 21-40 the GCS 255/190 HEARTBEAT;
      41 the GCS's ARM (COMMAND_LONG 400) to 1/1, 42 its ACK (the `command` event, dated 41); 43 1/1 armed;
      44-123 40 made-up senders 100+i/1, each a HEARTBEAT disarmed (a `vehicle` event) and one armed (an
      `arming` event); 124 1/1 disarmed (`arming`); 125-154 30 STATUSTEXTs of 1/1; 155-164 one STATUSTEXT
      each of 10 made-up senders 200+i/1.
    By hand: the 6 first events fill the bound (1, 41, 43, 44, 45, 46). Sender 101/1's arming (47) is the 7th:
    the least established sender is one with 2 frames (1/1 has 22, 255/190 21, 100/1 and 101/1 2), the newest
    group of those is 101/1's arming itself, given up; every later flood event likewise gives up itself (48-
    123: 76 more). 1/1's disarm (124) gives up the newest group of the least established, 101/1's vehicle
    event (46). 1/1's 30 STATUSTEXTs keep the first 2 and the last 2 (125, 126, 153, 154), 26 between left
    out; each made-up sender's STATUSTEXT (1 frame) then gives up itself (10). In all 77 + 1 + 26 + 10 = 114
    give-ups (vehicle 39, arming 39, statustext 36), said at the 1st, 2nd, 4th, ..., 64th: the events of
    frames 47, 48, 50, 54, 62, 78, 110 (give-up n for n <= 77 is frame 46 + n). Under the old policy (the
    first N of a kind) the vehicle's disarm at 124 was left out for the flood's."""
    from pymavlink.dialects.v20 import ardupilotmega as v2

    from mavscope.analysis.events import log

    for name, value in (("FIRST_KEPT", 2), ("LAST_KEPT", 2), ("MAX_EVENTS", 6), ("MAX_CHATTER", 4)):
        monkeypatch.setattr(log, name, value)
    veh, gcs = flows.Sender(1, 1), flows.Sender(255, 190)
    t = flows.T0
    entries = [(t + i * 0.05, veh.pack(_hb(False))) for i in range(20)]
    entries += [(t + 1 + i * 0.05, gcs.pack(_hb(False, gcs=True))) for i in range(20)]
    entries += [(t + 2, gcs.pack(flows.command_long(400, 1.0))),
                (t + 2.1, veh.pack(v2.MAVLink_command_ack_message(400, 0))), (t + 2.2, veh.pack(_hb(True)))]
    for i in range(40):
        made_up = flows.Sender(100 + i, 1)
        entries += [(t + 3 + i * 0.01, made_up.pack(_hb(False))), (t + 3.005 + i * 0.01, made_up.pack(_hb(True)))]
    entries.append((t + 4, veh.pack(_hb(False))))
    entries += [(t + 4.1 + i * 0.01, veh.pack(v2.MAVLink_statustext_message(6, b"text %d" % i))) for i in range(30)]
    entries += [(t + 5 + i * 0.01, flows.Sender(200 + i, 1).pack(v2.MAVLink_statustext_message(6, b"flood")))
                for i in range(10)]
    path = flows.write_tlog(tmp_path, entries)
    for environ in ENGINES:
        cli.environ = environ
        doc = cli.json("events", path)
        assert doc["counts"] == {"vehicle": 41, "arming": 42, "statustext": 40, "command": 1}
        assert [(e["frame"], e["kind"], e["from"]) for e in doc["events"]] == [
            (1, "vehicle", [1, 1]), (41, "command", [255, 190]), (43, "arming", [1, 1]),
            (44, "vehicle", [100, 1]), (45, "arming", [100, 1]), (124, "arming", [1, 1]),
            (125, "statustext", [1, 1]), (126, "statustext", [1, 1]), (153, "statustext", [1, 1]),
            (154, "statustext", [1, 1])]
        assert doc["dropped"] == {"vehicle": 39, "arming": 39, "statustext": 36}
        (said,) = [f for f in doc["findings"] if f["code"] == "capacity"]
        assert said["frames"] == [47, 48, 50, 54, 62, 78, 110] and "114 given up (114 events)" in said["message"]
        audit = findings(cli, "audit", path)
        assert said in audit["capacity"]
        status, out, _ = cli("events", path)
        assert "39 more arming events not listed" in out


def test_a_flood_of_mission_counts_and_requests_keeps_the_upload_under_way(  # type: ignore[no-untyped-def]
        cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """At most 3 transfers open and 2 MISSION_REQUEST_LISTs awaiting their COUNT. Built (records):
      1-2 HEARTBEATs of the vehicle 1/1 and the GCS 255/190; 3 the GCS's MISSION_COUNT 2 to 1/1, 4 the vehicle's
      MISSION_REQUEST_INT 0, 5 item 0; 6-11 six made-up GCSs 100+i/190 each a MISSION_COUNT 3 to 200+i/1 (never
      answered); 12 the GCS's MISSION_REQUEST_LIST of the fence (type 1) to 1/1; 13-15 three made-up GCSs
      150+i/190 the same; 16 the vehicle's MISSION_REQUEST_INT 1, 17 item 1, 18 its MISSION_ACK ACCEPTED; 19 the
      vehicle's MISSION_COUNT 0 of the fence to the GCS (the answer to record 12).
    By hand: the upload and the COUNTs of 6 and 7 fill the 3; the COUNT of 8 gives up the newest unanswered but
    itself (7), 9 gives up 8, 10 gives up 9, 11 gives up 10 (4 evicted). The REQUEST_LISTs: 12 and 13 fill the
    2; 14 gives up 13, 15 gives up 14. 6 give-ups, said at the 1st, 2nd and 4th: records 8, 9, 11. The upload
    completes (accepted, both items), the fence download pairs with its REQUEST_LIST (the old policy closed the
    oldest transfer: the upload, `evicted`, its ACK then matching nothing)."""
    import importlib

    from pymavlink.dialects.v20 import ardupilotmega as v20

    from mavscope.analysis.mission import answers, model

    reconstruct = importlib.import_module("mavscope.analysis.mission.reconstruct")  # (the package's name is a function)
    from tests.analysis.mission_exchange import Exchange, item_int

    monkeypatch.setattr(model, "OPEN_MAX", 3)
    monkeypatch.setattr(reconstruct, "OPEN_MAX", 3)
    monkeypatch.setattr(answers, "WAITING_MAX", 2)

    def made_up(x: Exchange, sysid: int, name: str, *args: object) -> None:
        mav = v20.MAVLink(None, srcSystem=sysid, srcComponent=190)
        x.t += 0.005
        x.frames.append((x.t, getattr(mav, f"{name.lower()}_encode")(*args).pack(mav)))

    x = Exchange()
    x.heartbeats(2, 3)
    x.send("gcs", "MISSION_COUNT", 1, 1, 2, 0)
    x.send("veh", "MISSION_REQUEST_INT", 255, 190, 0, 0)
    item_int(x, "gcs", (1, 1), 0, 16, 47.39, 8.54, 20)
    for i in range(6):
        made_up(x, 100 + i, "MISSION_COUNT", 200 + i, 1, 3, 0)
    x.send("gcs", "MISSION_REQUEST_LIST", 1, 1, 1)
    for i in range(3):
        made_up(x, 150 + i, "MISSION_REQUEST_LIST", 1, 1, 1)
    x.send("veh", "MISSION_REQUEST_INT", 255, 190, 1, 0)
    item_int(x, "gcs", (1, 1), 1, 16, 47.40, 8.55, 20)
    x.send("veh", "MISSION_ACK", 255, 190, 0, 0)
    x.send("veh", "MISSION_COUNT", 255, 190, 0, 1)
    assert len(x.frames) == 19
    path = x.tlog(tmp_path / "flood.tlog")
    for environ in ENGINES:
        cli.environ = environ
        doc = cli.json("mission", path)
        upload, *flood, fence = doc["transfers"]
        assert (upload["frames"][0], upload["outcome"], upload["closed"]) == (3, "complete", "ack")
        assert [t["closed"] for t in flood] == ["end", "evicted", "evicted", "evicted", "evicted", "end"]
        assert (fence["frames"], fence["direction"]) == ([12, 19], "download")
        (said,) = doc["findings"]
        assert said["code"] == "capacity" and said["frames"] == [8, 9, 11]
        assert "6 given up (6 exchanges)" in said["message"]
        assert said in findings(cli, "audit", path)["capacity"]
        assert said in findings(cli, "events", path)["capacity"]
        _, out, _ = cli("mission", path)
        assert "capacity" in out and "6 given up" in out


def test_a_flood_of_mission_counts_keeps_the_listing_of_the_upload_before_it(  # type: ignore[no-untyped-def]
        cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """At most 3 transfers listed. Built (records): 1-2 HEARTBEATs; 3-8 the GCS's accepted upload of 2 items to
    1/1 (COUNT, REQUEST_INT 0, item 0, REQUEST_INT 1, item 1, ACK); 9-18 ten made-up GCSs 100+i/190 each a
    MISSION_COUNT 3 to 200+i/1. By hand: the upload and the COUNTs of 9 and 10 fill the listing; each later
    COUNT (11-18) takes the newest listed but itself out of it (10, 11, ..., 17: 8 give-ups, said at the 1st,
    2nd, 4th and 8th: records 11, 12, 14, 18). Listed: the upload (complete) and the COUNTs of 9 and 18. Before,
    every transfer was listed, without bound (100,000 such COUNTs, a 2.4 MB tlog, took `mission` 590 MB)."""
    from pymavlink.dialects.v20 import ardupilotmega as v20

    from mavscope.analysis.mission import state
    from tests.analysis.mission_exchange import Exchange, item_int

    monkeypatch.setattr(state, "LISTED_MAX", 3)
    x = Exchange()
    x.heartbeats(2, 3)
    x.send("gcs", "MISSION_COUNT", 1, 1, 2, 0)
    for seq in range(2):
        x.send("veh", "MISSION_REQUEST_INT", 255, 190, seq, 0)
        item_int(x, "gcs", (1, 1), seq, 16, 47.39 + seq / 100, 8.54, 20)
    x.send("veh", "MISSION_ACK", 255, 190, 0, 0)
    for i in range(10):
        mav = v20.MAVLink(None, srcSystem=100 + i, srcComponent=190)
        x.t += 0.005
        x.frames.append((x.t, mav.mission_count_encode(200 + i, 1, 3, 0).pack(mav)))
    assert len(x.frames) == 18
    path = x.tlog(tmp_path / "listing.tlog")
    for environ in ENGINES:
        cli.environ = environ
        doc = cli.json("mission", path)
        assert [(t["frames"][0], t["outcome"]) for t in doc["transfers"]] == [
            (3, "complete"), (9, "abandoned"), (18, "abandoned")]
        (said,) = doc["findings"]
        assert said["frames"] == [11, 12, 14, 18] and "8 given up (8 exchanges)" in said["message"]
        assert said in findings(cli, "audit", path)["capacity"]


def test_events_say_the_commands_their_matcher_gave_up_and_audit_says_it_once(  # type: ignore[no-untyped-def]
        cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """At most 3 commands waiting for their ACK (command_log.PENDING_MAX). Built (records): 1 the GCS 255/190's
    ARM to 1/1; 2-6 COMMAND_LONGs 400 of made-up senders 100+i/1 to 1/1; 7 the vehicle's ACK (ACCEPTED) to
    255/190. By hand: the ARM and the commands of 2 and 3 fill the 3; 4, 5 and 6 each give up the newest waiting
    but themselves (3, 4, 5: 3 give-ups, said at the 1st and 2nd: records 4, 5). The ARM is answered at 7 (not
    given up), so `events` lists it ACCEPTED and says the give-ups; `audit` (which runs the same matching for
    itself and within the story) reports that finding once."""
    from pymavlink.dialects.v20 import ardupilotmega as v2

    from mavscope.analysis import command_log

    monkeypatch.setattr(command_log, "PENDING_MAX", 3)
    t = flows.T0
    entries = [(t, flows.Sender(255, 190).pack(flows.command_long(400, 1.0)))]
    entries += [(t + 0.1 * (i + 1), flows.Sender(100 + i, 1).pack(flows.command_long(400, 1.0))) for i in range(5)]
    entries.append((t + 1, flows.Sender(1, 1).pack(v2.MAVLink_command_ack_message(400, 0, 0, 0, 255, 190))))
    path = flows.write_tlog(tmp_path, entries)
    for environ in ENGINES:
        cli.environ = environ
        doc = cli.json("events", path)
        arm = [e for e in doc["events"] if e["kind"] == "command" and e["from"] == [255, 190]]
        assert [(e["frame"], "ACCEPTED" in e["text"]) for e in arm] == [(1, True)]
        (said,) = [f for f in doc["findings"] if f["code"] == "capacity"]
        assert said["frames"] == [4, 5] and "3 given up (3 commands)" in said["message"]
        assert findings(cli, "audit", path)["capacity"] == [said]
