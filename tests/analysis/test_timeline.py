"""Clock offsets, drift and round-trip times recovered from a capture with a known skew."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import CAPTURES, Cli
from tests.support import flows
from tests.support.captures import truth

SKEW = str(CAPTURES / "clock_skew.pcap")


def clocks(doc: dict, sysid: int) -> dict[str, dict]:
    (system,) = [s for s in doc["systems"] if s["sysid"] == sysid]
    return {c["source"]: c for c in system["clocks"]}


def test_vehicle_offset_and_drift(cli: Cli) -> None:
    t = truth("clock_skew.pcap")
    doc = cli.json("timeline", SKEW)
    v = clocks(doc, 1)
    first = doc["start"] - 1_773_482_400  # capture start is 10:00:00Z; the first frame comes a little later
    unix = v["SYSTEM_TIME.time_unix_usec"]
    assert unix["kind"] == "unix"
    assert unix["offset_s"] == pytest.approx(t["vehicle_utc_offset_s"] + first * t["vehicle_drift_ppm"] / 1e6,
                                             abs=1e-5)
    assert unix["drift_ppm"] == pytest.approx(t["vehicle_drift_ppm"], abs=0.5)
    assert unix["drift_err_ppm"] is not None and unix["drift_err_ppm"] < 0.5
    sig = v["signature link 0"]
    assert sig["offset_s"] == pytest.approx(t["vehicle_utc_offset_s"], abs=1e-4)
    assert sig["drift_ppm"] == pytest.approx(t["vehicle_drift_ppm"], abs=1)
    tc1 = v["TIMESYNC.tc1"]
    assert tc1["kind"] == "boot" and tc1["drift_ppm"] == pytest.approx(t["vehicle_drift_ppm"], abs=1)
    # the boot clock read zero this long (capture time) before the capture started
    assert 1_773_482_400 - tc1["zero_at"] == pytest.approx(t["vehicle_boot_before_capture_s"], abs=1e-3)
    assert v["time_boot_ms"]["drift_ppm"] == pytest.approx(t["vehicle_drift_ppm"], abs=10)


def test_gcs_clock_is_the_capture_clock_and_round_trips(cli: Cli) -> None:
    t = truth("clock_skew.pcap")
    doc = cli.json("timeline", SKEW)
    g = clocks(doc, 255)
    assert g["TIMESYNC.ts1"]["offset_s"] == pytest.approx(0, abs=1e-6)
    assert g["PING.time_usec"]["drift_ppm"] == pytest.approx(0, abs=0.1)
    (system,) = [s for s in doc["systems"] if s["sysid"] == 255]
    trips = {r["kind"]: r for r in system["round_trips"]}
    assert trips["TIMESYNC"]["rtt_ms"] == pytest.approx(t["timesync_rtt_ms"], abs=0.002)
    assert trips["PING"]["rtt_ms"] == pytest.approx(t["ping_rtt_ms"], abs=0.002)
    assert trips["TIMESYNC"]["peer"] == 1


def test_text_output(cli: Cli) -> None:
    status, out, _ = cli("timeline", SKEW)
    assert status == 0 and "System 1" in out and "SYSTEM_TIME.time_unix_usec" in out and "+250.0" in out
    assert "TIMESYNC round trips to system 1: 30" in out


def test_px4_session_clock(cli: Cli) -> None:
    # the generator's vehicle UTC clock runs 2150 µs ahead of the capture clock
    v = clocks(cli.json("timeline", str(CAPTURES / "px4_sitl_udp.pcap")), 1)
    assert v["SYSTEM_TIME.time_unix_usec"]["offset_s"] == pytest.approx(0.00215, abs=2e-6)


def test_no_drift_from_four_samples_in_half_a_second(cli: Cli, tmp_path: Path) -> None:
    """Issue: a drift of -9105.9 ppm from 4 samples over 0.5 s. Built here: SYSTEM_TIME 4 times in 0.5 s,
    the clock 1 s ahead of the capture with 5 ms of jitter."""
    v = flows.Sender(1, 1)
    entries = []
    for i, jitter in enumerate((0.0, 0.005, -0.004, 0.003)):
        t = flows.T0 + i * 0.16
        unix_us = round((t + 1.0 + jitter) * 1e6)
        entries.append((t, v.pack(flows.v2.MAVLink_system_time_message(unix_us, 1000 + i * 160))))
    doc = cli.json("timeline", flows.write_tlog(tmp_path, entries))
    clock = clocks(doc, 1)["SYSTEM_TIME.time_unix_usec"]
    assert clock["samples"] == 4 and clock["drift_ppm"] is None and clock["drift_err_ppm"] is None
    assert clock["offset_s"] == pytest.approx(1.0, abs=0.01)
    status, out, _ = cli("timeline", flows.write_tlog(tmp_path, entries, "b.tlog"))
    assert status == 0 and "-9105" not in out


def test_a_reboot_restarts_the_boot_clock_instead_of_bending_the_fit(cli: Cli, real_captures: Path) -> None:
    """px4_2018_params_offboard.tlog: the PX4 vehicle rebooted mid-capture. Read with pymavlink alone
    (tests/support/pymavlink_reader.py), its time_boot_ms falls from 944,625 ms to 3,238 ms once; the
    fit through both runs gave a drift of -1,683,346.7 ppm with 248 s of jitter. Now the clock restarts
    there, and its last run drifts by a few hundred ppm at most."""
    from tests.support.pymavlink_reader import read

    boots = [(m.time, m.msg.time_boot_ms) for m in read(real_captures / "px4_2018_params_offboard.tlog")
             if m.src == (1, 1) and hasattr(m.msg, "time_boot_ms")]
    falls = [t for (_, a), (t, b) in zip(boots, boots[1:], strict=False) if b < a - 1000]
    assert len(falls) == 1
    doc = cli.json("timeline", real_captures / "px4_2018_params_offboard.tlog")
    clock = next(c for s in doc["systems"] if s["sysid"] == 1 for c in s["clocks"] if c["source"] == "time_boot_ms")
    assert clock["restarts"] == 1 and clock["restarted_at"] == pytest.approx(falls)
    assert abs(clock["drift_ppm"]) < 1000 and clock["jitter_ms"] < 1000


def test_clocks_past_the_limit_are_counted_not_followed(cli: Cli, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A capture can name 65,280 senders x 256 signing links, a clock each (200,000 signed HEARTBEATs with
    random link ids held 380 MB of clocks). With the limit at 3: systems 1-5 each send two
    GLOBAL_POSITION_INTs (pymavlink), in two rounds; the clocks of 1-3 are followed (2 samples each), the
    4 readings of 4 and 5 are counted."""
    monkeypatch.setattr("mavscope.analysis.timeline.MAX_CLOCKS", 3)
    entries = []
    for k in range(10):
        sysid = 1 + k % 5
        msg = flows.v2.MAVLink_global_position_int_message(1000 * (k + 1), 0, 0, 0, 0, 0, 0, 0, 0)
        entries.append((flows.T0 + k, flows.Sender(sysid, 1, seq=k // 5).pack(msg)))
    path = flows.write_tlog(tmp_path, entries)
    doc = cli.json("timeline", path)
    assert [(s["sysid"], [c["samples"] for c in s["clocks"]]) for s in doc["systems"]] == [(1, [2]), (2, [2]), (3, [2])]
    assert doc["unfollowed_readings"] == 4
    status, out, _ = cli("timeline", path)
    assert status == 0 and "4 readings of clocks beyond the first 3 were not followed" in out


def test_an_unmeasured_drift_does_not_bend_the_offset(cli: Cli, real_captures: Path) -> None:
    """ap_sitl_attack1_signed_knownkey.pcap, read by scapy and pymavlink: ArduPilot's signing clock (system
    1, link 0) against capture time over 2.3 s, 272 samples, too short to measure a drift. Its offsets run
    from -10.1 s to -1.4 s (the clock steps forward near the end); a line through them put the offset at the
    first frame at -11.8 s, below every sample. With no drift measured the offset is their mean."""
    from pymavlink.dialects.v20 import all as mavlink
    from scapy.layers.inet import UDP
    from scapy.utils import rdpcap

    epoch = 1_420_070_400  # 2015-01-01T00:00:00Z, the signing timestamps' origin (10 µs units)
    offsets = []
    for pkt in rdpcap(str(real_captures / "ap_sitl_attack1_signed_knownkey.pcap")):
        if UDP not in pkt:
            continue
        mav = mavlink.MAVLink(None)
        mav.robust_parsing = True
        for m in mav.parse_buffer(bytes(pkt[UDP].payload)) or []:
            raw = bytes(m.get_msgbuf())
            if isinstance(m, mavlink.MAVLink_bad_data) or raw[0] != 0xFD or not raw[2] & 1:
                continue
            if raw[5] == 1 and raw[-13] == 0:  # system 1, link 0
                offsets.append(int.from_bytes(raw[-12:-6], "little") / 1e5 + epoch - float(pkt.time))
    assert len(offsets) == 272 and min(offsets) < -10 and max(offsets) > -1.5
    doc = cli.json("timeline", real_captures / "ap_sitl_attack1_signed_knownkey.pcap")
    clock = clocks(doc, 1)["signature link 0"]
    assert clock["drift_ppm"] is None
    assert clock["offset_s"] == pytest.approx(sum(offsets) / len(offsets), abs=1e-5)
