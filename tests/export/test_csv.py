"""`export -T csv` against mavlogdump (pymavlink's tool): the same header and cells per message type.

mavlogdump writes a row as `"{:.8f}".format(m._timestamp)` then `str(value)` per field of
`m.to_dict()`; the expected rows here are made that way from pymavlink reading the tlog itself, and
one type is compared with mavlogdump's own output. Timestamps agree to a microsecond: both are the
tlog's microseconds as a double, printed with 8 decimals, beyond a double's precision at 1.7e9 s
(pymavlink multiplies by 1e-6 where mavscope divides by 1e6: they may differ in the last bit).
"""

from __future__ import annotations

import csv
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

from pymavlink import mavutil

from tests.conftest import CAPTURES, Cli

TLOG = CAPTURES / "px4_sitl.tlog"


def _read(path: Path) -> list[list[str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.reader(f))


def _same_row(got: list[str], want: list[str]) -> bool:
    return abs(float(got[0]) - float(want[0])) < 1e-6 and got[1:] == want[1:]


def _pymavlink_rows() -> dict[str, list[list[str]]]:
    conn = mavutil.mavlink_connection(str(TLOG), dialect="all")
    out: dict[str, list[list[str]]] = defaultdict(list)
    while (m := conn.recv_match()) is not None:
        if m.get_type() == "BAD_DATA":
            continue
        data = m.to_dict()
        out[m.get_type()].append(["{:.8f}".format(m._timestamp)] + [str(data[f]) for f in m.fieldnames])
    return out


def test_every_message_type_as_pymavlink_reads_it(cli: Cli, tmp_path: Path) -> None:
    status, out, err = cli("export", str(TLOG), "-T", "csv", "-o", str(tmp_path))
    assert status == 0, err
    folder = tmp_path / TLOG.name
    want = _pymavlink_rows()
    assert sorted(p.stem for p in folder.glob("*.csv")) == sorted(want)
    for msg, rows in want.items():
        got = _read(folder / f"{msg}.csv")
        cls = getattr(mavutil.mavlink, f"MAVLink_{msg.lower()}_message")
        assert got[0] == ["timestamp"] + [f"{msg}.{f}" for f in cls.fieldnames]
        assert len(got) - 1 == len(rows), msg
        for g, w in zip(got[1:], rows):
            assert _same_row(g, w), (msg, g, w)


def test_a_type_as_mavlogdump_prints_it(cli: Cli, tmp_path: Path) -> None:
    mavlogdump = Path(sys.executable).parent / "mavlogdump.py"
    dumped = subprocess.run([sys.executable, str(mavlogdump), "--format", "csv", "--types", "GPS_RAW_INT", str(TLOG)],
                            capture_output=True, text=True, check=True).stdout.splitlines()
    assert cli("export", str(TLOG), "-T", "csv", "-o", str(tmp_path)).status == 0
    got = (tmp_path / TLOG.name / "GPS_RAW_INT.csv").read_text().splitlines()
    assert got[0] == dumped[0] and len(got) == len(dumped) > 10
    for g, d in zip(got[1:], dumped[1:]):
        assert _same_row(g.split(","), d.split(","))


def test_two_captures_of_one_name_get_two_folders(cli: Cli, tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for d, src in (("a", TLOG), ("b", CAPTURES / "serial_dump.raw")):
        (tmp_path / d / "cap.bin").write_bytes(src.read_bytes())
    out = tmp_path / "out"
    status, text, err = cli("export", str(tmp_path / "a" / "cap.bin"), str(tmp_path / "b" / "cap.bin"),
                            "-T", "csv", "-o", str(out))
    assert status == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["cap.bin", "cap.bin.2"]
    # serial_dump.raw has no capture time: an empty timestamp, as a raw stream has none
    assert _read(out / "cap.bin.2" / "HEARTBEAT.csv")[1][0] == ""
