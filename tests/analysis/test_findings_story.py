"""The control and GNSS findings (mavscope.analysis.control, .gnss): on the incident captures exactly as
the generator's truth files list them (captures/*.truth.json, written from what was sent), and on flows
built here with pymavlink, whose expected answer follows from how they were built."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mavscope.analysis.control import ControlSources
from mavscope.analysis.expert import expert_findings
from mavscope.analysis.gnss import MAX_SENDERS, GnssAnomalies
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import decode_payload
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import CAPTURES
from tests.support import flows
from tests.support.builders import heartbeat_msg, vehicle_heartbeat_msg
from tests.support.captures import frames
from tests.support.flows import T0, Sender, write_tlog

v2 = flows.v2
NEW = {"second-gcs-control", "unexpected-mode-change", "unexpected-mission-clear", "in-flight-disarm",
       "gnss-position-jump", "gnss-fix-collapse", "ekf-gnss-alarm", "gnss-time-jump"}


def _found(fs) -> dict[str, list[list[int]]]:  # type: ignore[no-untyped-def]
    out: dict[str, list[list[int]]] = {}
    for f in fs:
        if f.code in NEW:
            out.setdefault(f.code, []).append(list(f.frames))
    return out


@pytest.mark.parametrize("name", ["gcs_takeover.pcap", "gps_spoof.pcap"])
def test_incident_findings_are_the_truth(dialect: Dialect, name: str) -> None:
    truth = json.loads((CAPTURES / name.replace(".pcap", ".truth.json")).read_text(encoding="utf-8"))
    got = _found(expert_findings(frames(name, dialect), dialect))
    assert {k: sorted(v) for k, v in got.items()} == {k: sorted(v) for k, v in truth["findings"].items()}


def test_spoof_jump_sizes(dialect: Dialect) -> None:
    """The generator moved the GNSS position 700 m east (flat metres: 111320 m per degree of latitude, times
    cos(latitude) per degree of longitude); the great-circle distance between the degE7 positions agrees."""
    truth = json.loads((CAPTURES / "gps_spoof.truth.json").read_text(encoding="utf-8"))
    g = GnssAnomalies(dialect)
    for f in frames("gps_spoof.pcap", dialect):
        if f.msgdef is not None and f.msgdef.name in g.wants:
            g.add(f, decode_payload(f))
    worst = {msg: ep.worst for (code, _, msg), ep in g.found.items() if code == "gnss-position-jump"}
    assert worst["GPS_RAW_INT"] == pytest.approx(truth["spoof"]["jump_east_m"], rel=0.005)
    assert worst["GLOBAL_POSITION_INT"] == pytest.approx(truth["spoof"]["jump_east_m"], rel=0.005)
    times = {msg: ep.worst for (code, _, msg), ep in g.found.items() if code == "gnss-time-jump"}
    assert times == {"SYSTEM_TIME": pytest.approx(truth["time_jump"]["seconds"], abs=0.01)}


def test_other_bundled_captures_have_none_of_these(dialect: Dialect) -> None:
    for name in ("px4_sitl_udp.pcap", "commands_ack.pcap", "clock_skew.pcap", "mission_resend.pcap",
                 "mavlink_v1_udp.pcap", "px4_sitl.tlog", "signed_udp.pcap"):
        assert _found(expert_findings(frames(name, dialect), dialect)) == {}, name


# --- flows built here -------------------------------------------------------------------------------

def _findings(tmp: Path, entries: list[tuple[float, bytes]], dialect: Dialect) -> dict[str, list[list[int]]]:
    with open_capture(write_tlog(tmp, entries)) as r:
        return _found(expert_findings((f for f in Dissector(dialect).run(r) if type(f) is not Anomaly), dialect))


def _vehicle_hb(armed: bool, mode: int = 5, mav_type: int = 2) -> object:
    return vehicle_heartbeat_msg(armed, mode, mav_type)


def _gcs_hb() -> object:
    return heartbeat_msg(6, 8)


def _gpi(boot_ms: int, lat: int, lon: int, rel_mm: int = 20_000, vx: int = 500) -> object:
    return v2.MAVLink_global_position_int_message(boot_ms, lat, lon, rel_mm + 488_000, rel_mm, vx, 0, 0, 0)


def test_two_ground_stations_asking_for_data_is_no_takeover(tmp_path: Path, dialect: Dialect) -> None:
    veh, qgc, mp = Sender(1, 1), Sender(255, 190), Sender(254, 190)
    entries = [(T0, veh.pack(_vehicle_hb(False))), (T0, qgc.pack(_gcs_hb())), (T0, mp.pack(_gcs_hb())),
               (T0 + 1, qgc.pack(flows.command_long(400, 1.0))), (T0 + 2, veh.pack(_vehicle_hb(True)))]
    for i in range(5):  # both ask for messages and home while the vehicle is armed: not control
        entries += [(T0 + 3 + i, mp.pack(flows.command_long(512, 33.0))),
                    (T0 + 3.5 + i, qgc.pack(flows.command_long(410, 0.0))),
                    (T0 + 3.7 + i, mp.pack(v2.MAVLink_request_data_stream_message(1, 1, 0, 4, 1)))]
    assert _findings(tmp_path, entries, dialect) == {}


def test_manual_control_from_a_second_station_while_armed(tmp_path: Path, dialect: Dialect) -> None:
    veh, qgc, other = Sender(1, 1), Sender(255, 190), Sender(77, 190)
    entries = [(T0, veh.pack(_vehicle_hb(False))), (T0 + 0.1, qgc.pack(flows.command_long(400, 1.0))),
               (T0 + 1, veh.pack(_vehicle_hb(True))),
               (T0 + 2, other.pack(v2.MAVLink_rc_channels_override_message(1, 1, *[1500] * 8))),
               (T0 + 2.1, other.pack(flows.manual_control())),
               (T0 + 3, veh.pack(_vehicle_hb(False))),  # disarmed: control passes on
               (T0 + 4, other.pack(flows.manual_control()))]
    assert _findings(tmp_path, entries, dialect) == {"second-gcs-control": [[4, 5]]}


def test_in_flight_disarm_from_relative_altitude_and_not_on_the_ground(tmp_path: Path, dialect: Dialect) -> None:
    veh, gcs = Sender(1, 1), Sender(255, 190)
    flying = [(T0, veh.pack(_vehicle_hb(True))), (T0 + 0.5, veh.pack(_gpi(1000, 473977419, 85455938, 30_000))),
              (T0 + 0.6, gcs.pack(flows.command_long(400, 0.0))), (T0 + 1, veh.pack(_vehicle_hb(False)))]
    assert _findings(tmp_path, flying, dialect) == {"in-flight-disarm": [[3, 4]]}
    veh = Sender(1, 1)
    landed = [(T0, veh.pack(_vehicle_hb(True))), (T0 + 0.5, veh.pack(_gpi(1000, 473977419, 85455938, 300))),
              (T0 + 1, veh.pack(_vehicle_hb(False)))]
    assert _findings(tmp_path, landed, dialect) == {}
    rover = Sender(1, 1)  # a ground rover has no "in the air"
    driving = [(T0, rover.pack(_vehicle_hb(True, mav_type=10))),
               (T0 + 0.5, rover.pack(_gpi(1000, 473977419, 85455938, 30_000))),
               (T0 + 1, rover.pack(_vehicle_hb(False, mav_type=10)))]
    assert _findings(tmp_path, driving, dialect) == {}


def test_jumps_are_judged_by_the_vehicles_clock_not_capture_time(tmp_path: Path, dialect: Dialect) -> None:
    """A SITL run at 25x: 0.2 s of vehicle time (time_boot_ms) per 8 ms of capture time. At 5 m/s the
    vehicle moves 1 m per message: nothing to report, though 1 m in 8 ms would be 125 m/s."""
    veh = Sender(1, 1)
    per_deg = 111_320.0 / 1e7  # m per degE7 of latitude
    entries = [(T0 + i * 0.008, veh.pack(_gpi(1000 + 200 * i, 473977419 + round(i / per_deg), 85455938)))
               for i in range(200)]
    assert _findings(tmp_path, entries, dialect) == {}
    veh = Sender(1, 1)  # the same track with one 300 m step: a jump
    entries = [(T0 + i * 0.008, veh.pack(_gpi(1000 + 200 * i, 473977419 + round((i + (300 if i >= 100 else 0))
                                                                                  / per_deg), 85455938)))
               for i in range(200)]
    assert _findings(tmp_path, entries, dialect) == {"gnss-position-jump": [[101]]}


def test_a_reboot_starts_the_gnss_state_over(tmp_path: Path, dialect: Dialect) -> None:
    veh = Sender(1, 1)
    entries = [(T0 + i * 0.2, veh.pack(_gpi(50_000 + 200 * i, 473977419, 85455938, vx=0))) for i in range(5)]
    # rebooted (the boot clock restarts) somewhere 5 km away: no jump
    entries += [(T0 + 2 + i * 0.2, veh.pack(_gpi(1_000 + 200 * i, 474427419, 85455938, vx=0))) for i in range(5)]
    assert _findings(tmp_path, entries, dialect) == {}


def _gps(usec: int, fix: int, sats: int, lat: int = 473977419) -> object:
    return v2.MAVLink_gps_raw_int_message(usec, fix, lat, 85455938, 500_000, 90, 140, 0, 0, sats)


def test_fix_collapse_but_not_a_receiver_going_away(tmp_path: Path, dialect: Dialect) -> None:
    veh = Sender(1, 1)
    entries = [(T0 + i, veh.pack(_gps(10_000_000 + i * 1_000_000, 3, 17))) for i in range(3)]
    entries += [(T0 + 3, veh.pack(_gps(13_000_000, 0, 17)))]  # NO_GPS (ArduSub's GPS_INPUT pausing)
    entries += [(T0 + 4 + i, veh.pack(_gps(14_000_000 + i * 1_000_000, 3, 17))) for i in range(2)]
    assert _findings(tmp_path, entries, dialect) == {}
    entries += [(T0 + 6, veh.pack(_gps(16_000_000, 3, 4)))]  # 17 -> 4 satellites within a second
    assert _findings(tmp_path, entries, dialect) == {"gnss-fix-collapse": [[7]]}


def _ekf(flags: int, pos_var: float = 0.1) -> object:
    return v2.MAVLink_ekf_status_report_message(flags, 0.1, pos_var, 0.1, 0.05, 0.0)


def test_ekf_alarms_only_after_the_filter_was_healthy(tmp_path: Path, dialect: Dialect) -> None:
    veh = Sender(1, 1)
    starting = [(T0, veh.pack(_ekf(0x400))), (T0 + 1, veh.pack(_ekf(0xA7, 3.0)))]  # initialising, no GPS yet
    assert _findings(tmp_path, starting, dialect) == {}
    veh = Sender(1, 1)
    healthy = [(T0, veh.pack(_ekf(0x33F))), (T0 + 1, veh.pack(_ekf(0x33F, 1.2))), (T0 + 2, veh.pack(_ekf(0x33F))),
               (T0 + 3, veh.pack(_ekf(0x400))), (T0 + 4, veh.pack(_ekf(0xA7)))]  # a reset after, then no GPS
    assert _findings(tmp_path, healthy, dialect) == {"ekf-gnss-alarm": [[2]]}


def test_gps_utc_against_system_time(tmp_path: Path, dialect: Dialect) -> None:
    """GPS_RAW_INT.time_usec in UTC (as PX4 SITL sends it) 30 s off the UTC of SYSTEM_TIME and the boot clock."""
    veh = Sender(1, 1)
    unix = 1_773_482_400_000_000
    entries = [(T0, veh.pack(v2.MAVLink_system_time_message(unix, 100_000))),
               (T0 + 0.5, veh.pack(_gpi(100_500, 473977419, 85455938, vx=0))),
               (T0 + 0.6, veh.pack(_gps(unix + 600_000, 3, 15))),
               (T0 + 1.6, veh.pack(_gps(unix + 1_600_000 + 30_000_000, 3, 15)))]
    assert _findings(tmp_path, entries, dialect) == {"gnss-time-jump": [[4]]}


def test_state_is_bounded_whatever_the_senders(tmp_path: Path, dialect: Dialect) -> None:
    """A capture with 6241 senders (every sysid/compid pair of 1..79) of GPS_RAW_INT and HEARTBEAT: the state is
    bounded by the number of senders there can be (MAX_SENDERS: 256 x 256 pairs), so every one is followed and
    none given up (docs/security.md, "Bounds")."""
    entries = []
    for n, s in enumerate(Sender(a, b) for a in range(1, 80) for b in range(1, 80)):
        entries += [(T0 + n * 1e-4, s.pack(_gps(1_000_000 + n, 3, 12))), (T0 + n * 1e-4, s.pack(_vehicle_hb(True)))]
    g, c = GnssAnomalies(dialect), ControlSources(dialect)
    with open_capture(write_tlog(tmp_path, entries)) as r:
        for f in Dissector(dialect).run(r):
            if type(f) is not Anomaly:
                fields = decode_payload(f)
                g.add(f, fields)
                c.add(f, fields)
    assert MAX_SENDERS == 256 * 256
    assert len(g.senders) == 79 * 79 and len(c.systems.last) == 79 * 79
