"""`mavscope read` through the real entry point with a fake environment (stdout, stderr, status)."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from mavscope.cli import ExitStatus
from tests.conftest import ROOT, Cli
from tests.support import pmav
from tests.support.builders import write_pcap, write_udp_pcap

SCHEMA = json.loads((ROOT / "docs" / "frame.schema.json").read_text())


@pytest.fixture()
def sample(tmp_path: Path) -> Path:
    """A small UDP capture: a clean session plus the damage a reader must report."""
    vehicle, gcs = pmav.mav2(1, 1), pmav.mav2(255, 190)
    bad = bytearray(pmav.heartbeat(vehicle))
    bad[-3] ^= 0x55
    nan_attitude = vehicle.attitude_encode(5, float("nan"), float("inf"), 0.5, 0, 0, 0).pack(vehicle)
    packets = [
        (("127.0.0.1", 14580), ("127.0.0.1", 14550), pmav.heartbeat(vehicle)),
        (("127.0.0.1", 14550), ("127.0.0.1", 14580), pmav.heartbeat(gcs)),
        (("127.0.0.1", 14550), ("127.0.0.1", 14580), pmav.command_long_rtl(gcs)),
        (("127.0.0.1", 14580), ("127.0.0.1", 14550), pmav.statustext(vehicle, "two") + nan_attitude),
        (("127.0.0.1", 14580), ("127.0.0.1", 14550), b"junk" + bytes(bad)),
        (("127.0.0.1", 14580), ("127.0.0.1", 14550), pmav.heartbeat(vehicle)[:15]),
        (("10.0.0.1", 53), ("10.0.0.2", 53), b"\xfd\x01not mavlink at all"),
    ]
    return write_udp_pcap(tmp_path / "sample.pcap", packets, t0=1_700_000_000, step=0.25)


def test_summary_lines(cli: Cli, sample: Path) -> None:
    status, out, err = cli("read", str(sample))
    assert status == ExitStatus.OK
    lines = out.splitlines()
    assert len(lines) == 7  # the DNS datagram is not MAVLink
    assert "COMMAND_LONG command=MAV_CMD_NAV_RETURN_TO_LAUNCH" in lines[2]
    assert lines[3].lstrip().startswith("4 ") and lines[4].lstrip().startswith("4.2 ")
    assert "[CRC bad]" in lines[5] and "[CRC truncated]" in lines[6]
    assert err == ""


def test_jsonl_contract(cli: Cli, sample: Path) -> None:
    status, out, _ = cli("read", str(sample), "-T", "jsonl")
    assert status == ExitStatus.OK
    objs = [json.loads(line) for line in out.splitlines()]
    for obj in objs:
        jsonschema.validate(obj, SCHEMA)
    assert [(o["frame"], o["index"]) for o in objs] == [(1, 1), (2, 1), (3, 1), (4, 1), (4, 2), (5, 1), (6, 1)]
    assert [o["crc_status"] for o in objs] == ["ok", "ok", "ok", "ok", "ok", "bad", "truncated"]
    att = objs[4]
    assert att["msgname"] == "ATTITUDE" and att["fields"]["roll"] is None and att["fields"]["pitch"] is None
    assert objs[3]["fields"]["text"] == "two"
    assert objs[0]["src"] == "127.0.0.1:14580" and objs[0]["transport"] == "udp"
    assert objs[0]["time"] == pytest.approx(1_700_000_000)
    assert [n["code"] for n in objs[5]["notes"]] == ["skipped-bytes", "bad-crc"]
    assert objs[5]["notes"][0]["offset"] > 0
    assert objs[6]["fields"] is None and objs[6]["crc"] is None


def test_json_array_equals_jsonl(cli: Cli, sample: Path) -> None:
    _, out_json, _ = cli("read", str(sample), "-T", "json")
    _, out_jsonl, _ = cli("read", str(sample), "-T", "jsonl")
    assert json.loads(out_json) == [json.loads(line) for line in out_jsonl.splitlines()]


def test_count_verbose_hex(cli: Cli, sample: Path) -> None:
    status, out, _ = cli("read", str(sample), "-c", "3", "-V", "-x")
    assert status == 0
    assert out.count("Header (MAVLink v2)") == 3
    assert "command: MAV_CMD_NAV_RETURN_TO_LAUNCH (20)" in out
    assert "CRC: 0x" in out and "[ok]" in out
    assert "0000  fd " in out


def test_write_round_trip(cli: Cli, sample: Path, tmp_path: Path) -> None:
    out_pcap = tmp_path / "out.pcap"
    status, _, _ = cli("read", str(sample), "-c", "4", "-w", str(out_pcap), "-q")
    assert status == 0
    _, out, _ = cli("read", str(out_pcap), "-T", "jsonl")
    objs = [json.loads(line) for line in out.splitlines()]
    # -c 4 stops after 4 frames: records 1-4 (the 4th record holds two frames, both come along).
    assert [o["msgname"] for o in objs] == ["HEARTBEAT", "HEARTBEAT", "COMMAND_LONG", "STATUSTEXT", "ATTITUDE"]


def test_empty_capture(cli: Cli, tmp_path: Path) -> None:
    empty = tmp_path / "empty.pcap"
    write_pcap(empty, [])
    assert cli("read", str(empty), "-T", "json")[:2] == (0, "[]\n")


@pytest.mark.parametrize(
    "argv, message",
    [
        (("read",), "capture file is required"),
        (("read", "/nonexistent/capture.pcap"), "/nonexistent/capture.pcap"),
        (("read", "x.pcap", "-T", "xml"), "invalid choice"),
        (("read", "x.pcap", "-c", "0"), "argument -c: a whole positive number of frames, not '0'"),
        (("read", "x.pcap", "-c", "1e3"), "argument -c: a whole positive number of frames, not '1e3'"),
        (("frobnicate",), "invalid choice"),
    ],
)
def test_usage_errors_exit_2_with_one_line(cli: Cli, argv: tuple[str, ...], message: str) -> None:
    status, out, err = cli(*argv)
    assert status == ExitStatus.ERROR
    assert message in err and err.count("\n") == 1 and err.startswith("mavscope: ")
    assert out == ""


def test_directory_is_a_clear_error(cli: Cli, tmp_path: Path) -> None:
    status, _, err = cli("read", str(tmp_path))
    assert status == ExitStatus.ERROR and str(tmp_path) in err and err.count("\n") == 1


def test_dialect_option_adds_messages(cli: Cli, sample: Path, tmp_path: Path) -> None:
    xml = tmp_path / "extra.xml"
    xml.write_text(
        '<?xml version="1.0"?><mavlink><version>3</version><dialect>0</dialect><messages>'
        '<message id="61042" name="MAVSCOPE_TEST"><description>test</description>'
        '<field type="uint16_t" name="value" units="m">a value</field></message></messages></mavlink>'
    )
    from mavscope.mavlink.dialect import load_dialect

    d = load_dialect([xml])
    md = d.messages[61042]
    mav = pmav.mav2()
    frame = bytearray(b"\xfd\x02\x00\x00\x07\x01\x01" + (61042).to_bytes(3, "little") + b"\x34\x12")
    from fastcrc import crc16

    crc = crc16.mcrf4xx(md.crc_extra_byte, crc16.mcrf4xx(bytes(frame[1:])))
    frame += crc.to_bytes(2, "little")
    cap = tmp_path / "custom.pcap"
    write_udp_pcap(cap, [(("127.0.0.1", 14580), ("127.0.0.1", 14550), bytes(frame) + pmav.heartbeat(mav))])
    _, without, _ = cli("read", str(cap), "-T", "jsonl")
    _, with_dialect, _ = cli("read", str(cap), "-T", "jsonl", "--dialect", str(xml))
    assert json.loads(without.splitlines()[0])["crc_status"] == "unchecked"
    obj = json.loads(with_dialect.splitlines()[0])
    assert (obj["msgname"], obj["crc_status"], obj["fields"]) == ("MAVSCOPE_TEST", "ok", {"value": 0x1234})
