"""Conformance on real captures made by other people (../shared/real-captures, see its PROVENANCE.md).

The expected counts are PROVENANCE.md's: CRC-valid frames found by an independent scanner (pymavlink).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus
from tests.conftest import Cli
from tests.crosscheck.test_pymavlink import dissect

EXPECTED = {
    # file: ({(version, crc_status): count of CRC-valid frames}, transport)
    "ipal_transcriber_MAVLink.pcap": ({(2, "ok"): 10}, "udp"),
    "judep90_serial_over_tcp_socat.pcapng": ({(2, "ok"): 7}, "tcp"),
    "ardusub_log_tools_small.tlog": ({(2, "ok"): 35912}, "tlog"),
    "bluerobotics_mavlink_server_blueos_00025.tlog": ({(2, "ok"): 30437, (1, "ok"): 2}, "tlog"),
    "gomavlib_signed_testvectors_key4F_DERIVED.raw": ({(2, "ok"): 2}, "raw"),
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_crc_valid_counts_match_provenance(name: str, real_captures: Path, dialect: Dialect) -> None:
    expected, transport = EXPECTED[name]
    frames, _ = dissect(real_captures / name, dialect)
    valid = Counter((f.version, f.crc_status.value) for f in frames if f.crc_status is CrcStatus.OK)
    assert dict(valid) == expected
    assert {f.transport for f in frames} == {transport}


def test_ardusub_bad_crc_frames_are_camera_messages(real_captures: Path, dialect: Dialect) -> None:
    # Four frames from the camera manager (compid 100) carry CRCs made with other CRC_EXTRAs; pymavlink
    # rejects them too. They are reported, not dropped.
    frames, _ = dissect(real_captures / "ardusub_log_tools_small.tlog", dialect)
    bad = [f for f in frames if f.crc_status is CrcStatus.BAD]
    assert [(f.compid, f.msgname) for f in bad] == [
        (100, "CAMERA_INFORMATION"), (100, "VIDEO_STREAM_INFORMATION"), (100, "CAMERA_SETTINGS"),
        (100, "CAMERA_CAPTURE_STATUS"),
    ]


def test_tcp_stream_frames(real_captures: Path, dialect: Dialect) -> None:
    frames, anomalies = dissect(real_captures / "judep90_serial_over_tcp_socat.pcapng", dialect)
    assert all(str(f.src) == "127.0.0.1:5760" for f in frames) and not anomalies
    assert [(f.record, f.index, f.msgname) for f in frames][4:6] == [(5, 1, "ATTITUDE"), (5, 2, "ATTITUDE_QUATERNION")]
    # File offsets point at the STX byte of each frame.
    raw = (real_captures / "judep90_serial_over_tcp_socat.pcapng").read_bytes()
    assert all(raw[f.offset : f.offset + len(f.raw)] == f.raw for f in frames if f.offset is not None)


def test_gomavlib_signed_vectors(real_captures: Path, dialect: Dialect) -> None:
    frames, _ = dissect(real_captures / "gomavlib_signed_testvectors_key4F_DERIVED.raw", dialect)
    sigs = [(f.msgname, f.signature.link_id, f.signature.timestamp) for f in frames if f.signature]
    assert sigs == [("HEARTBEAT", 1, 2), ("OPTICAL_FLOW", 3, 4)]


TLOGS = ["ap_plane_sitl_mission3types_ftp_mp_mavproxy.tlog", "ap_rover_mission_fence_rally_params.tlog",
         "ardusub_log_tools_small.tlog", "bluerobotics_mavlink_server_blueos_00025.tlog",
         "px4_2018_params_offboard.tlog", "px4flow_v1_encapsulated_data.tlog"]


@pytest.mark.parametrize("name", TLOGS)
def test_tlog_messages_match_pymavlink_record_by_record(name: str, real_captures: Path, dialect: Dialect) -> None:
    """Every CRC-valid frame of each real tlog, counted per sender and message, equals what pymavlink's
    MAVLink.decode() finds reading the same file record by record (tests/support/pymavlink_reader.py, which
    imports nothing of mavscope). The rover tlog starts with SITL console text in one-byte records: it must be
    read as a tlog (not a raw stream) and lose none of its 96,646 frames, as pymavlink's mavutil does."""
    from tests.support.pymavlink_reader import read

    expected = Counter((m.src, m.name) for m in read(real_captures / name))
    frames, _ = dissect(real_captures / name, dialect)
    got = Counter(((f.sysid, f.compid), f.msgname) for f in frames if f.crc_status is CrcStatus.OK)
    assert {f.transport for f in frames} == {"tlog"}
    assert got == expected


def test_the_injected_command_verifies_with_the_known_key_from_a_day_ahead(cli: Cli, real_captures: Path) -> None:
    """ap_sitl_attack1_signed_knownkey.pcap (PROVENANCE.md): one COMMAND_LONG from 255/230 injected into a
    signed ArduPilot SITL link. Derived apart from mavscope (pymavlink decode, the spec's
    sha256(key + frame[:-6])[:6] by hand): it is record 161 (index 160), link 1, and verifies with
    SHA-256("key"); its signature time 1780984472.86799 lies 86,398.2 s after its capture time. The
    vehicle's 272 frames verify with none of the candidate keys. A receiver keeps the newest timestamp it
    accepted, so this frame would move its signing clock a day ahead."""
    rows = cli.jsonl(real_captures / "ap_sitl_attack1_signed_knownkey.pcap", "--key", "passphrase:key")
    valid = [r for r in rows if r["signature"] and r["signature"]["status"] == "valid"]
    assert [(r["frame"], r["sysid"], r["compid"], r["msgname"], r["signature"]["link_id"]) for r in valid] == [
        (161, 255, 230, "COMMAND_LONG", 1)]
    assert valid[0]["signature"]["skew"] == pytest.approx(86398.2, abs=0.1)
    assert any(n["code"] == "signature-skew" and "after capture time" in n["message"] for n in valid[0]["notes"])
    assert sum(r["signature"]["status"] == "invalid" for r in rows if r["sysid"] == 1) == 272
