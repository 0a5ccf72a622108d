"""Events and the new findings on the real captures of ../shared/real-captures (PROVENANCE.md there):
ArduPilot (Rover/boat, Plane, Copter) SITL, ArduSub, PX4, Mission Planner, QGroundControl, MAVProxy.

Independent sources:
- tests/support/real_truth.py (pymavlink's messages and the protocols' rules, no mavscope import): commands
  with their ACK, parameter sets and their confirmation, MAVLink FTP file reads, signing streams.
- pymavlink read here (tests/support/pymavlink_reader.py): the vehicle HEARTBEATs, from which the arming
  and custom-mode transitions are counted in the test, the STATUSTEXT frames, whose chunks are joined
  by the protocol's rule (same id; a chunk shorter than 50 characters ends the text), and the PARAM_VALUE
  frames, whose values changing with no set before them are listed in the test.

No capture raises any of the control or GNSS findings: QGroundControl, Mission Planner and MAVProxy
commanding one vehicle side by side (plane), the autotest GCS 250/250 (rover), ArduSub's MANUAL_CONTROL
(QGC), its GPS_INPUT feed pausing (fix type 0 with 21 satellites), ArduPlane's position before its EKF
origin is set (offsets from 0, 0), and the rover's 25x SITL speed-up are all normal.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from mavscope.analysis.events import story
from mavscope.analysis.expert import expert_findings
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.support import real_truth
from tests.support.pymavlink_reader import Msg, read, read_pcap

NEW = {"second-gcs-control", "unexpected-mode-change", "unexpected-mission-clear", "in-flight-disarm",
       "gnss-position-jump", "gnss-fix-collapse", "ekf-gnss-alarm", "gnss-time-jump"}
# MAV_TYPEs that are no vehicle (common.xml: GCS, onboard controller, gimbal, ADS-B, camera, ...)
NOT_VEHICLES = {6, 18, 26, 27, 30, 31, 32, 33, 34, 36, 37, 38, 39, 40, 41, 42, 44}
CAPTURES = ["ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog", "ap_rover_mission_fence_rally_params.tlog",
            "ap_sitl_attack1_signed_knownkey.pcap", "ardusub_log_tools_small.tlog",
            "bluerobotics_mavlink_server_blueos_00025.tlog", "gomavlib_signed_testvectors_key4F_DERIVED.raw",
            "ipal_transcriber_MAVLink.pcap", "judep90_serial_over_tcp_socat.pcapng", "px4_2018_params_offboard.tlog",
            "px4_fw_mission_download_raw.bin", "px4flow_v1_encapsulated_data.tlog"]
_cache: dict[str, tuple] = {}  # type: ignore[type-arg]


def _analyse(path: Path, dialect: Dialect) -> tuple:  # type: ignore[type-arg]
    """(events, findings) of a real capture, computed once per test session."""
    if path.name not in _cache:
        with open_capture(str(path)) as r:
            fs = [f for f in Dissector(dialect).run(r) if type(f) is not Anomaly]
        _cache[path.name] = (story(fs, dialect), expert_findings(fs, dialect))
    return _cache[path.name]


def _pymavlink(path: Path) -> list[Msg]:
    return read_pcap(path) if path.suffix == ".pcap" else read(path)


@pytest.mark.parametrize("name", CAPTURES)
def test_no_control_or_gnss_finding(real_captures: Path, dialect: Dialect, name: str) -> None:
    _, findings = _analyse(real_captures / name, dialect)
    assert [f for f in findings if f.code in NEW] == []


@pytest.mark.parametrize("name", [c for c in CAPTURES if not c.endswith(".pcapng")])  # the TCP one: 7 frames
def test_heartbeat_transitions(real_captures: Path, dialect: Dialect, name: str) -> None:
    path = real_captures / name
    result, _ = _analyse(path, dialect)
    last: dict[tuple[int, int], tuple[bool, int]] = {}
    arming, modes = [], []
    for m in _pymavlink(path):
        if m.name != "HEARTBEAT" or m.msg.autopilot == 8 or m.msg.type in NOT_VEHICLES:
            continue
        armed, custom = bool(m.msg.base_mode & 128), m.msg.custom_mode
        prev = last.get(m.src)
        if prev is not None and prev[0] != armed:
            arming.append((m.time, m.src, armed))
        if prev is not None and prev[1] != custom:
            modes.append((m.time, m.src, custom))
        last[m.src] = (armed, custom)
    got_arming = [(e.time, e.sender, e.details["armed"]) for e in result.events if e.kind == "arming"]
    got_modes = [(e.time, e.sender, e.details["custom_mode"]) for e in result.events if e.kind == "mode"]
    assert got_arming == [(pytest.approx(t), s, a) for t, s, a in arming]
    assert got_modes == [(pytest.approx(t) if t is not None else None, s, c) for t, s, c in modes]
    assert [e.sender for e in result.events if e.kind == "vehicle" and "now reports" not in e.text] == list(last)


def test_transition_counts(real_captures: Path, dialect: Dialect) -> None:
    """What the HEARTBEATs say, written out for reading (the loop above derives them from pymavlink)."""
    counts = {}
    for name in ("ap_rover_mission_fence_rally_params.tlog", "ardusub_log_tools_small.tlog",
                 "px4_2018_params_offboard.tlog", "ap_sitl_attack1_signed_knownkey.pcap"):
        events = _analyse(real_captures / name, dialect)[0].events
        counts[name] = (sum(e.kind == "arming" for e in events), sum(e.kind == "mode" for e in events))
    # rover: armed and disarmed twice by the autotest GCS, MANUAL <-> AUTO around a reboot (INITIALISING);
    # ArduSub: armed once, disarmed once, always MANUAL; PX4 2018: STABILIZED/MANUAL/ALTCTL switches from
    # the RC, never armed; the signed attack: GUIDED -> LAND, asked by the injected command
    assert counts == {"ap_rover_mission_fence_rally_params.tlog": (4, 6), "ardusub_log_tools_small.tlog": (2, 0),
                      "px4_2018_params_offboard.tlog": (0, 8), "ap_sitl_attack1_signed_knownkey.pcap": (0, 1)}


@pytest.mark.parametrize("name", ["ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog",
                                  "ap_rover_mission_fence_rally_params.tlog", "ap_sitl_attack1_signed_knownkey.pcap",
                                  "ardusub_log_tools_small.tlog", "px4_2018_params_offboard.tlog"])
def test_commands_as_pymavlink_reads_them(real_captures: Path, dialect: Dialect, name: str) -> None:
    result, _ = _analyse(real_captures / name, dialect)
    want = sorted((c["attempts"][0], c["command"], c["ack"]["result"] if c["ack"] else None)
                  for c in real_truth.commands(_pymavlink(real_captures / name)))
    got = sorted((e.time, e.details["command_id"], e.details["result_id"]) for e in result.events
                 if e.kind == "command" and e.details.get("message") != "SET_MODE")
    assert got == [(pytest.approx(t), c, r) for t, c, r in want]


def test_parameter_sets_as_pymavlink_reads_them(real_captures: Path, dialect: Dialect) -> None:
    name = "ap_rover_mission_fence_rally_params.tlog"
    result, _ = _analyse(real_captures / name, dialect)
    truth = real_truth.param_sets(_pymavlink(real_captures / name))
    want = [(s["time"], s["name"], s["value"], s["confirmed"]) for s in truth]
    sets = [e for e in result.events if e.kind == "param" and e.details["what"] == "set"]
    got = [(e.time, e.details["name"], e.details["value"], e.details["confirmed"]) for e in sets]
    assert len(want) == 55 and got == [(pytest.approx(t), n, pytest.approx(v), c) for t, n, v, c in want]
    # latency_s: from the set to the PARAM_VALUE that confirmed it
    assert [e.details["latency_ms"] for e in sets] == [pytest.approx(s["latency_s"] * 1000, abs=0.002)
                                                       for s in truth]


def test_parameter_changes_no_set_explains(real_captures: Path, dialect: Dialect) -> None:
    """A PARAM_VALUE whose value (as float32) differs from the component's last one for that name, and that
    is not the first report of the name after a PARAM_SET of it: counted here from pymavlink's frames (the
    rover changes some itself: STAT_BOOTCNT after its reboot, ground pressures and gyro offsets it
    calibrates, MIS_TOTAL as missions are written, STAT_RUNTIME)."""
    name = "ap_rover_mission_fence_rally_params.tlog"
    result, _ = _analyse(real_captures / name, dialect)
    last: dict[tuple[tuple[int, int], str], bytes] = {}
    awaiting: set[tuple[int, str]] = set()
    want = []
    for m in _pymavlink(real_captures / name):
        if m.name == "PARAM_SET":
            awaiting.add((m.msg.target_system, m.msg.param_id))
        elif m.name == "PARAM_VALUE":
            pid, raw = m.msg.param_id, struct.pack("<f", m.msg.param_value)
            answer = (m.src[0], pid) in awaiting
            awaiting.discard((m.src[0], pid))
            if (m.src, pid) in last and last[(m.src, pid)] != raw and not answer:
                want.append((m.time, m.src, pid, m.msg.param_value))
            last[(m.src, pid)] = raw
    got = [(e.time, e.sender, e.details["name"], e.details["value"]) for e in result.events
           if e.kind == "param" and e.details["what"] == "change"]
    assert want and got == [(pytest.approx(t), s, n, pytest.approx(v)) for t, s, n, v in want]


def test_ftp_opens_as_pymavlink_reads_them(real_captures: Path, dialect: Dialect) -> None:
    """Each OpenFileRO: an accepted one is a file event of the file read (session, size
    announced), a refused one a file event of the operation with the server's NAK."""
    name = "ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog"
    result, _ = _analyse(real_captures / name, dialect)
    reads = real_truth.ftp_reads(_pymavlink(real_captures / name))
    want = [(r["open_time"], r["path"], r.get("session"), r.get("announced_size"),
             f"NAK {r['open_nak']}" if r.get("open_nak") else None) for r in reads]
    files = [e for e in result.events if e.kind == "file"]
    got = [(e.time, e.details["path"], e.details.get("session"), e.details.get("announced_size"),
            e.details.get("result")) for e in files if e.details.get("object") == "ftp-read"
           or e.details.get("opcode") == "OpenFileRO"]
    assert got == [(pytest.approx(t), p, s, z, n) for t, p, s, z, n in want]
    objects = {e.details["session"]: e.details for e in files if e.details.get("object") == "ftp-read"}
    for r in reads:
        if r.get("session") is not None:
            d = objects[r["session"]]
            assert (d["size"], d["sha256"], d["gaps"], d["complete"]) == (r["length"], r["sha256"], r["gaps"], True)


def test_signed_attack_story(real_captures: Path, dialect: Dialect) -> None:
    name = "ap_sitl_attack1_signed_knownkey.pcap"
    result, _ = _analyse(real_captures / name, dialect)
    signing = real_truth.signing_streams(_pymavlink(real_captures / name))
    assert sorted(f"{e.sender[0]}/{e.sender[1]} link {e.details['link_id']}" for e in result.events
                  if e.kind == "signing") == sorted(signing)
    (cmd,) = [e for e in result.events if e.kind == "command"]
    # pymavlink: MAV_CMD_DO_SET_MODE 217 / 9 from 255/230 to 1/0, ACCEPTED 5 ms later; ArduCopter mode 9 is LAND
    assert (cmd.sender, cmd.target, cmd.details["command_id"], cmd.details["result_id"], cmd.details["mode"]) == \
        ((255, 230), (1, 0), 176, 0, "LAND")
    (mode,) = [e for e in result.events if e.kind == "mode"]
    assert (mode.details["previous"], mode.details["mode"]) == ("GUIDED", "LAND") and mode.frame > cmd.frame


@pytest.mark.parametrize("name", ["ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog",
                                  "ap_rover_mission_fence_rally_params.tlog", "ardusub_log_tools_small.tlog",
                                  "bluerobotics_mavlink_server_blueos_00025.tlog", "px4_2018_params_offboard.tlog"])
def test_statustexts(real_captures: Path, dialect: Dialect, name: str) -> None:
    # QGroundControl's rule (StatusTextHandler.cc): one text in progress per sender; id 0 whole; another id
    # ends the text in progress, its end missing; a chunk shorter than 50 characters ends it; 1 s without
    # a chunk ends it, its end missing (mavscope writes "[end not seen]", "[chunk k missing]")
    texts, open_chunks = [], {}

    def close(src: tuple[int, int], complete: bool) -> None:
        first, _, parts, _ = open_chunks.pop(src)
        out, k, top = "", 0, max(parts)
        while k <= top:
            if k in parts:
                out, k = out + parts[k], k + 1
                continue
            j = k
            while j + 1 not in parts:
                j += 1
            out, k = out + (f"[chunk {k} missing]" if j == k else f"[chunks {k}-{j} missing]"), j + 1
        texts.append((first, out + ("" if complete else "[end not seen]")))

    for m in _pymavlink(real_captures / name):
        if m.name != "STATUSTEXT":
            continue
        cur = open_chunks.get(m.src)
        if cur is not None and (cur[1] != m.msg.id or m.time - cur[3] > 1.0):
            close(m.src, False)
        if m.msg.id == 0:
            texts.append((m.time, m.msg.text))
            continue
        first, _, parts, _ = open_chunks.setdefault(m.src, (m.time, m.msg.id, {}, m.time))
        parts[m.msg.chunk_seq] = m.msg.text
        open_chunks[m.src] = (first, m.msg.id, parts, m.time)
        if len(m.msg.text) < 50:
            close(m.src, True)
    for src in list(open_chunks):  # unfinished at the end
        close(src, False)
    result, _ = _analyse(real_captures / name, dialect)
    got = [(e.time, e.details["message"]) for e in result.events
           if e.kind == "statustext" or (e.kind == "failsafe" and e.details.get("source") == "STATUSTEXT")]
    assert sorted(got) == [(pytest.approx(t), x) for t, x in sorted(texts)]
