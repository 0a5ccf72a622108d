"""The flight's story (mavscope.analysis.events, `mavscope events`): on the incident captures against the
generator's truth files (captures/*.truth.json, written from what it sent), and on small flows built here
with pymavlink, whose expected events follow from how they were built."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

from mavscope.analysis.events import EventLog, story
from mavscope.analysis.events import log as event_log
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import CAPTURES, Cli
from tests.support import flows
from tests.support.builders import vehicle_heartbeat_msg
from tests.support.captures import frames
from tests.support.flows import T0, Sender, write_tlog

TAKEOVER = json.loads((CAPTURES / "gcs_takeover.truth.json").read_text(encoding="utf-8"))
SPOOF = json.loads((CAPTURES / "gps_spoof.truth.json").read_text(encoding="utf-8"))
v2 = flows.v2


def _events(name: str, dialect: Dialect):  # type: ignore[no-untyped-def]
    return story(frames(name, dialect), dialect).events


def _of(events, kind: str):  # type: ignore[no-untyped-def]
    return [e for e in events if e.kind == kind]


@pytest.mark.parametrize("name, truth", [("gcs_takeover.pcap", TAKEOVER), ("gps_spoof.pcap", SPOOF)])
def test_arming_and_modes_as_the_generator_set_them(dialect: Dialect, name: str, truth: dict) -> None:
    events = _events(name, dialect)
    assert [(e.frame, e.details["armed"], e.details["mode"]) for e in _of(events, "arming")] == \
        [(a["record"], a["armed"], a["mode"]) for a in truth["arming"]]
    assert [(e.frame, e.details["previous"], e.details["mode"]) for e in _of(events, "mode")] == \
        [(m["record"], m["from"], m["to"]) for m in truth["modes"]]
    frames_in_order = [e.frame for e in events]
    assert frames_in_order == sorted(frames_in_order)


@pytest.mark.parametrize("name, truth", [("gcs_takeover.pcap", TAKEOVER), ("gps_spoof.pcap", SPOOF)])
def test_commands_with_their_ack(dialect: Dialect, name: str, truth: dict) -> None:
    got = [(e.frame, list(e.sender), e.details["command_id"], e.details["result_id"], e.details["ack_frame"],
            e.details.get("mode")) for e in _of(_events(name, dialect), "command") if e.details.get("command_id")]
    assert got == [(c["record"], c["from"], c["command"], c["result"], c["ack_record"], c["mode"])
                   for c in truth["commands"]]


def test_takeover_story(dialect: Dialect) -> None:
    events = _events("gcs_takeover.pcap", dialect)
    set_modes = [(e.frame, e.details["mode"]) for e in _of(events, "command") if e.details.get("message") == "SET_MODE"]
    t = TAKEOVER
    assert set_modes == [(t["intruder_control_records"][1], "POSCTL"), (t["intruder_control_records"][17], "POSCTL")]
    mission = {e.details["what"]: e for e in _of(events, "mission") if e.details["what"] in ("clear-all", "transfer")}
    assert mission["clear-all"].frame == t["mission_clear_record"] and mission["clear-all"].sender == (42, 190)
    assert mission["transfer"].frame == t["mission_upload_record"] and mission["transfer"].details["complete"]
    reached = [[e.frame, e.details["seq"]] for e in _of(events, "mission") if e.details["what"] == "reached"]
    assert reached == t["mission_items_reached"]
    assert [e.frame for e in _of(events, "statustext")] == t["statustext_records"]
    # the intruder's last HEARTBEAT is at 41.3 s of a 60 s capture: silent for the rest of it
    (lost,) = _of(events, "link")
    assert lost.sender == (42, 190) and lost.details["what"] == "lost" and 18 < lost.details["silent_s"] < 19


def test_spoof_story_failsafes(dialect: Dialect) -> None:
    events = _events("gps_spoof.pcap", dialect)
    failsafes = [(e.frame, e.details["source"], e.details.get("active")) for e in _of(events, "failsafe")]
    land = next(m["record"] for m in SPOOF["modes"] if m["to"] == "LAND")
    disarm = next(a["record"] for a in SPOOF["arming"] if not a["armed"])
    # the generator: STATUSTEXT "EKF Failsafe..." at 32.0 s, MAV_STATE_CRITICAL from 32.0 s to 47.5 s
    assert failsafes == [(SPOOF["failsafe_statustext_record"], "STATUSTEXT", None), (land, "HEARTBEAT", True),
                         (disarm, "HEARTBEAT", False)]


def test_cli_events_json_filter_and_kinds(cli: Cli) -> None:
    doc = cli.json("events", CAPTURES / "gcs_takeover.pcap")
    assert [e["frame"] for e in doc["events"] if e["kind"] == "arming"] == [a["record"] for a in TAKEOVER["arming"]]
    first = doc["events"][0]
    assert set(first) == {"time", "frame", "kind", "from", "to", "text", "details"}
    assert {f["code"] for f in doc["findings"]} >= {"second-gcs-control", "in-flight-disarm"}
    only = cli.json("events", CAPTURES / "gcs_takeover.pcap", "--kind", "mode", "--kind", "arming")
    assert {e["kind"] for e in only["events"]} == {"mode", "arming"}
    assert len(only["events"]) == len(TAKEOVER["modes"]) + len(TAKEOVER["arming"])
    # -Y selects the events dated by a matched frame (every frame is still analysed)
    sel = cli.json("events", CAPTURES / "gcs_takeover.pcap", "-Y", "mavlink.sysid == 42")
    assert sel["events"] and all(e["from"][0] == 42 for e in sel["events"])
    status, out, err = cli("events", CAPTURES / "gcs_takeover.pcap")
    assert status == 0 and "AUTO.MISSION -> AUTO.LOITER" in out and "in-flight-disarm" in out


# --- flows built here -------------------------------------------------------------------------------

def _story(path: str, dialect: Dialect):  # type: ignore[no-untyped-def]
    with open_capture(path) as r:
        return story((f for f in Dissector(dialect).run(r) if type(f) is not Anomaly), dialect)


def _hb(mode: int = 5, armed: bool = False, status: int = 4) -> object:
    return vehicle_heartbeat_msg(armed, mode, system_status=status)


def test_statustext_chunks_are_joined_and_failsafe_texts_marked(tmp_path: Path, dialect: Dialect) -> None:
    s = Sender(1, 1)
    first, second = "x" * 50, "end of a long text"
    entries = [(T0, s.pack(v2.MAVLink_statustext_message(4, first.encode(), 7, 0))),
               (T0 + 0.01, s.pack(v2.MAVLink_statustext_message(4, second.encode(), 7, 1))),
               (T0 + 0.02, s.pack(v2.MAVLink_statustext_message(2, b"Radio Failsafe - Continuing Auto")))]
    events = _story(write_tlog(tmp_path, entries), dialect).events
    assert [(e.kind, e.frame, e.details["message"]) for e in events] == [
        ("statustext", 1, first + second), ("failsafe", 3, "Radio Failsafe - Continuing Auto")]
    assert events[0].details["severity"] == "WARNING" and events[0].details["chunks"] == 2


def test_parameter_sets_confirmed_or_not(tmp_path: Path, dialect: Dialect) -> None:
    gcs, veh = Sender(255, 190), Sender(1, 1)
    f32 = 9  # MAV_PARAM_TYPE_REAL32
    entries = [(T0, veh.pack(v2.MAVLink_param_value_message(b"WP_SPEED", 2.0, f32, 10, 3))),
               (T0 + 1, gcs.pack(v2.MAVLink_param_set_message(1, 1, b"WP_SPEED", 5.0, f32))),
               (T0 + 1.01, veh.pack(v2.MAVLink_param_value_message(b"WP_SPEED", 5.0, f32, 10, 3))),
               (T0 + 2, gcs.pack(v2.MAVLink_param_set_message(1, 1, b"FENCE_ENABLE", 1.0, f32))),
               (T0 + 2.01, veh.pack(v2.MAVLink_param_value_message(b"FENCE_ENABLE", 0.0, f32, 10, 4))),
               (T0 + 20, veh.pack(v2.MAVLink_param_value_message(b"OTHER", 0.0, f32, 10, 5))),
               (T0 + 21, veh.pack(v2.MAVLink_param_value_message(b"WP_SPEED", 7.0, f32, 10, 3)))]
    params = _of(_story(write_tlog(tmp_path, entries), dialect).events, "param")
    # the sets: WP_SPEED answered with the value set 10 ms later, FENCE_ENABLE answered with 0 (kept);
    # WP_SPEED reported as 7 with no set before it; OTHER's first value is no change
    assert [(e.frame, e.details["what"], e.details["name"], e.details["value"], e.details["previous"],
             e.details["confirmed"], e.details["confirm_frame"], e.details["reported"]) for e in params] == [
        (2, "set", "WP_SPEED", 5.0, 2.0, True, 3, 5.0), (4, "set", "FENCE_ENABLE", 1.0, None, False, 5, 0.0),
        (7, "change", "WP_SPEED", 7.0, 5.0, None, None, None)]
    assert params[0].details["latency_ms"] == pytest.approx(10.0, abs=0.01)
    assert params[0].text == "255/190 sets 1/1 WP_SPEED = 5 (was 2): confirmed in 10.0 ms"
    assert params[1].text.startswith("255/190 sets 1/1 FENCE_ENABLE = 1: not confirmed: 1/1 reports 0; "
                                     "security-relevant (fence, unsigned)")
    assert (params[1].details["security"], params[1].details["disables"]) == ("fence", None)  # 1 enables it
    assert params[2].sender == (1, 1) and "no set to explain it" in params[2].text


def _ftp(sender: Sender, target: tuple[int, int], seq: int, opcode: int, data: bytes = b"", session: int = 0,
         req: int = 0, size: int | None = None) -> bytes:
    """FILE_TRANSFER_PROTOCOL with an FTP header as the MAVLink FTP spec lays it out (<HBBBBBBI, then data)."""
    payload = struct.pack("<HBBBBBBI", seq, session, opcode, len(data) if size is None else size, req, 0, 0, 0) + data
    return sender.pack(v2.MAVLink_file_transfer_protocol_message(0, target[0], target[1],
                                                                 list(payload.ljust(251, b"\0"))))


def test_file_transfers_with_their_answer(tmp_path: Path, dialect: Dialect) -> None:
    gcs, veh = Sender(255, 190), Sender(1, 1)
    open_ro, remove, ack, nak = 4, 8, 128, 129
    entries = [(T0, _ftp(gcs, (1, 1), 1, open_ro, b"@PARAM/param.pck\0")),
               (T0 + 0.01, _ftp(veh, (255, 190), 2, ack, struct.pack("<I", 17220), session=3, req=open_ro)),
               (T0 + 1, _ftp(gcs, (1, 1), 3, remove, b"/logs/1.bin\0")),
               (T0 + 1.01, _ftp(veh, (255, 190), 4, nak, bytes([10]), req=remove)),
               (T0 + 2, _ftp(gcs, (1, 1), 5, open_ro, b"/nothing\0"))]
    files = _of(_story(write_tlog(tmp_path, entries), dialect).events, "file")
    # the open ACKed (session 3, 17,220 bytes announced) but no data read: an object with nothing received;
    # the removal refused (error 10 is FileNotFound in the FTP spec); the last open never answered
    (read, removal, unanswered) = files
    assert (read.frame, read.details["what"], read.details["object"], read.details["path"], read.details["session"],
            read.details["announced_size"], read.details["received"], read.details["complete"]) == \
        (1, "object", "ftp-read", "@PARAM/param.pck", 3, 17220, 0, False)
    assert (read.sender, read.target) == ((1, 1), (255, 190))
    assert [(e.frame, e.details["opcode"], e.details["path"], e.details["result"]) for e in (removal, unanswered)] == [
        (3, "RemoveFile", "/logs/1.bin", "NAK FileNotFound"), (5, "OpenFileRO", "/nothing", None)]
    assert removal.text == "255/190 -> 1/1 RemoveFile /logs/1.bin: NAK FileNotFound"
    assert unanswered.text.endswith("OpenFileRO /nothing: no answer")


def test_signing_events(tmp_path: Path, dialect: Dialect) -> None:
    s = Sender(1, 1)
    s.mav.signing.secret_key = bytes(32)
    s.mav.signing.sign_outgoing = True
    s.mav.signing.link_id = 2
    s.mav.signing.timestamp = 1
    entries = [(T0 + i, s.pack(_hb())) for i in range(3)]
    s.mav.signing.sign_outgoing = False
    entries += [(T0 + 3 + i, s.pack(_hb())) for i in range(2)]
    gcs = Sender(255, 190)
    entries.append((T0 + 6, gcs.pack(v2.MAVLink_setup_signing_message(1, 1, bytes(range(32)), 0))))
    signing = _of(_story(write_tlog(tmp_path, entries), dialect).events, "signing")
    assert [(e.frame, e.details["what"]) for e in signing] == [(1, "signed"), (4, "unsigned"), (6, "setup-signing")]
    assert signing[1].details["frames"] == 2
    assert all("000102" not in e.text for e in signing)  # the key is never shown


def test_link_loss_and_recovery_and_reboot(tmp_path: Path, dialect: Dialect) -> None:
    veh = Sender(1, 1)
    entries = [(T0 + i, veh.pack(_hb())) for i in range(5)]  # heartbeats at 1 Hz...
    entries += [(T0 + 13 + i, veh.pack(_hb())) for i in range(3)]  # ...then nothing for 9 s
    entries.append((T0 + 16, veh.pack(v2.MAVLink_system_time_message(0, 900_000))))
    entries.append((T0 + 17, veh.pack(v2.MAVLink_system_time_message(0, 2_000))))  # the boot clock went back
    events = _story(write_tlog(tmp_path, entries), dialect).events
    link = _of(events, "link")
    assert [(e.frame, e.details["what"], e.details["silent_s"]) for e in link] == [(5, "lost", 9.0),
                                                                                   (6, "recovered", 9.0)]
    (reboot,) = _of(events, "reboot")
    assert reboot.frame == 10 and (reboot.details["before_ms"], reboot.details["after_ms"]) == (900_000, 2_000)


def test_events_of_a_kind_and_sender_are_capped(tmp_path: Path, dialect: Dialect,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """30 STATUSTEXTs from 1/1 (records 1-30), then its HEARTBEAT (31). With the first 5 and the last 5 of a kind
    and sender listed: records 1-5 and 26-30, the 20 between left out (counted, and said as a capacity
    finding); the HEARTBEAT's vehicle event is another kind, listed."""
    monkeypatch.setattr(event_log, "FIRST_KEPT", 5)
    monkeypatch.setattr(event_log, "LAST_KEPT", 5)
    s = Sender(1, 1)
    entries = [(T0 + i * 0.01, s.pack(v2.MAVLink_statustext_message(6, b"spam"))) for i in range(30)]
    entries.append((T0 + 1, s.pack(_hb())))
    result = _story(write_tlog(tmp_path, entries), dialect)
    assert [e.frame for e in _of(result.events, "statustext")] == [1, 2, 3, 4, 5, 26, 27, 28, 29, 30]
    assert result.dropped["statustext"] == 20
    assert result.counts["statustext"] == 30 and len(_of(result.events, "vehicle")) == 1
    (said,) = result.capacity
    assert said.code == "capacity" and "20 given up (20 events)" in said.message


def test_sources_are_pluggable(dialect: Dialect) -> None:
    """Another analysis adds its records as events by handing EventLog its own source factories."""
    class Every100:
        wants: frozenset[str] = frozenset()

        def add(self, f, fields):  # type: ignore[no-untyped-def]
            return [event_log.Event(f.time, f.record, "param", (f.sysid, f.compid), "x")] if f.record % 100 == 0 else []

        def finish(self):  # type: ignore[no-untyped-def]
            return []

    log = EventLog(dialect, [lambda systems, d: Every100()])
    for f in frames("gcs_takeover.pcap", dialect):
        log.add(f)
    assert [e.frame for e in log.finish().events] == list(range(100, 701, 100))


def test_command_texts_name_what_was_asked(tmp_path: Path, dialect: Dialect) -> None:
    gcs, veh = Sender(255, 190), Sender(1, 1)
    entries = [(T0, veh.pack(_hb())),
               (T0 + 1, gcs.pack(flows.command_long(400, 2.0))),  # COMPONENT_ARM_DISARM with param1 2: neither
               (T0 + 1.01, veh.pack(v2.MAVLink_command_ack_message(400, 4, 0, 0, 255, 190))),
               (T0 + 2, gcs.pack(v2.MAVLink_command_long_message(1, 1, 176, 0, 1, 6, 0, 0, 0, 0, 0))),  # Copter RTL
               (T0 + 3, gcs.pack(v2.MAVLink_set_mode_message(1, 1, 9)))]  # LAND
    cmds = _of(_story(write_tlog(tmp_path, entries), dialect).events, "command")
    assert [e.text for e in cmds] == ["255/190 -> 1/1 COMPONENT_ARM_DISARM (param1 2.0): FAILED in 10.0 ms",
                                      "255/190 -> 1/1 DO_SET_MODE to RTL: no ACK in the capture",
                                      "255/190 -> 1 SET_MODE LAND"]


REAL_TLOGS = ["ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog", "ap_rover_mission_fence_rally_params.tlog",
              "ardusub_log_tools_small.tlog", "bluerobotics_mavlink_server_blueos_00025.tlog",
              "px4_2018_params_offboard.tlog", "px4flow_v1_encapsulated_data.tlog"]


@pytest.mark.parametrize("name", REAL_TLOGS)
def test_reboots_on_real_tlogs_are_where_the_boot_clock_falls(cli: Cli, real_captures: Path, name: str) -> None:
    """Read with pymavlink alone (tests/support/pymavlink_reader.py): per sender, the time_boot_ms of its
    SYSTEM_TIME, ATTITUDE, GLOBAL_POSITION_INT and RC_CHANNELS (0 left out: ground stations send it),
    in capture order; a fall of a second or more is a reboot. PX4 in 2017 sent no SYSTEM_TIME: its reboot
    (px4_2018_params_offboard.tlog, 944,625 ms to 3,238 ms, in RC_CHANNELS first) was missed when only
    SYSTEM_TIME was read. The rover's shows in ATTITUDE before SYSTEM_TIME."""
    from tests.support.pymavlink_reader import read

    last: dict[tuple[int, int], int] = {}
    expected = []
    for m in read(real_captures / name):
        if m.name in ("SYSTEM_TIME", "ATTITUDE", "GLOBAL_POSITION_INT", "RC_CHANNELS") and m.msg.time_boot_ms:
            before = last.get(m.src)
            if before is not None and m.msg.time_boot_ms <= before - 1000:
                expected.append((list(m.src), before, m.msg.time_boot_ms))
            last[m.src] = m.msg.time_boot_ms
    doc = cli.json("events", real_captures / name)
    got = [(e["from"], e["details"]["before_ms"], e["details"]["after_ms"]) for e in doc["events"]
           if e["kind"] == "reboot"]
    assert got == expected
    assert bool(expected) == (name in ("ap_rover_mission_fence_rally_params.tlog", "px4_2018_params_offboard.tlog"))
