"""`mavscope sql`: views over a dataset and over raw captures (exported to a temporary dataset first);
the issue's example query against the signature verdicts of `read -T jsonl` with the same key."""

from __future__ import annotations

import csv
import io
import json
from collections import Counter
from datetime import datetime
from pathlib import Path

from tests.conftest import CAPTURES, Cli

SIGNED = CAPTURES / "signed_udp.pcap"
WRONG_KEY = "hex:" + "11" * 32  # not the capture's key: every signature is invalid


def test_the_issue_example_over_raw_captures(cli: Cli) -> None:
    query = "SELECT sysid, count(*) AS n FROM frames WHERE signature_status = 'invalid' GROUP BY 1 ORDER BY 1"
    status, out, err = cli("sql", query, str(SIGNED), "--json", "--key", WRONG_KEY)
    assert status == 0, err
    want = Counter(r["sysid"] for r in cli.jsonl(str(SIGNED), "--key", WRONG_KEY)
                   if r["signature"] and r["signature"]["status"] == "invalid")
    assert want and json.loads(out) == [{"sysid": k, "n": v} for k, v in sorted(want.items())]


def test_views_over_a_dataset(cli: Cli, tmp_path: Path) -> None:
    root = tmp_path / "ds"
    paths = [CAPTURES / "px4_sitl_udp.pcap", CAPTURES / "mavlink_v1_udp.pcap", CAPTURES / "commands_ack.pcap"]
    assert cli("export", *map(str, paths), "--parquet", str(root))[0] == 0
    q = "SELECT table_name FROM information_schema.tables ORDER BY 1"
    names = {r["table_name"] for r in json.loads(cli("sql", q, str(root), "--json").out)}
    assert {"frames", "findings", "anomalies", "captures", "HEARTBEAT", "GLOBAL_POSITION_INT"} <= names
    # message rows per capture, as many as frames of that message with decoded fields in the JSON
    q = ("SELECT c.name, count(*) AS n FROM HEARTBEAT h JOIN captures c USING (capture_id) "
         "GROUP BY 1 ORDER BY 1")
    got = {r["name"]: r["n"] for r in json.loads(cli("sql", q, str(root), "--json").out)}
    want = {p.name: sum(1 for r in cli.jsonl(str(p)) if r["msgname"] == "HEARTBEAT" and r["fields"]) for p in paths}
    assert got == want
    # findings are the stats, audit, objects and params commands' findings
    q = "SELECT source, code FROM findings JOIN captures USING (capture_id) WHERE name = 'commands_ack.pcap'"
    rows = json.loads(cli("sql", q, str(root), "--json").out)
    want = []
    for command in ("stats", "audit", "objects", "params"):
        _, out, _ = cli(command, str(paths[2]), "--json")
        want += [(command, f["code"]) for f in json.loads(out)["findings"]]
    assert sorted((r["source"], r["code"]) for r in rows) == sorted(want)


def test_output_formats(cli: Cli) -> None:
    q = ("SELECT msgname, count(*) AS n, min(signature_time) AS t FROM frames WHERE msgname = 'COMMAND_LONG' "
         "GROUP BY 1")
    status, out, err = cli("sql", q, str(SIGNED), "--csv")
    assert status == 0, err
    rows = list(csv.DictReader(io.StringIO(out)))
    commands = [r for r in cli.jsonl(str(SIGNED)) if r["msgname"] == "COMMAND_LONG"]
    assert [(r["msgname"], int(r["n"])) for r in rows] == [("COMMAND_LONG", len(commands))]
    first = min(datetime.fromisoformat(r["signature"]["time"]) for r in commands)
    assert datetime.fromisoformat(rows[0]["t"]) == first
    # bytes as hex in JSON
    status, out, _ = cli("sql", "SELECT payload, len FROM frames WHERE frame = 1 AND index = 1", str(SIGNED), "--json")
    row = json.loads(out)[0]
    assert len(bytes.fromhex(row["payload"])) == row["len"] == cli.jsonl(str(SIGNED))[0]["len"]
    # the text table says NULL for a null
    status, out, _ = cli("sql", "SELECT 1 AS one, NULL AS nothing", str(SIGNED))
    assert status == 0 and "one" in out and "NULL" in out and "1 row(s)" in out


def test_errors_are_one_line(cli: Cli, tmp_path: Path) -> None:
    status, out, err = cli("sql", "SELECT nope FROM frames", str(SIGNED))
    assert status == 2 and err.startswith("mavscope: sql:") and err.count("\n") == 1 and "nope" in err
    status, _, err = cli("sql", "SELECT 1", str(tmp_path / "missing"))
    assert status == 2 and "no such file or directory" in err


def test_integer_sums_print_as_integers(cli: Cli) -> None:
    # DuckDB sums integers as HUGEINT, which reaches Arrow as decimal(38, 0): the sum of sysid over every
    # frame of px4_sitl_udp.pcap, from the generator's frame list (captures/expected.json: record, index,
    # sysid, compid, seq, msgid)
    name = "px4_sitl_udp.pcap"
    frames = json.loads((CAPTURES / "expected.json").read_text())[name]["frame_list"]
    want = sum(f[2] for f in frames)
    q = "SELECT sum(sysid) AS s, 1.50::DECIMAL(5, 2) AS d FROM frames"
    status, out, err = cli("sql", q, str(CAPTURES / name))
    assert status == 0, err
    assert f" {want} " in out and f"{want}.0" not in out
    assert " 1.50 " in out  # a decimal in its own scale
    assert json.loads(cli("sql", q, str(CAPTURES / name), "--json").out) == [{"s": want, "d": 1.5}]
    assert cli("sql", q, str(CAPTURES / name), "--csv").out == f"s,d\n{want},1.50\n"
    # beyond 64 bits: exact in the table and the CSV (JSON has a float there: orjson writes 64-bit integers)
    big = (1 << 64) + 5
    status, out, _ = cli("sql", f"SELECT {big}::HUGEINT * 1 AS b, sum(x) AS t FROM (VALUES ({big}::HUGEINT)) v(x)",
                         str(CAPTURES / name), "--csv")
    assert status == 0 and out == f"b,t\n{big},{big}\n"


def test_a_missing_view_is_named_with_those_there_are(cli: Cli, tmp_path: Path) -> None:
    # a capture without MAVLink frames: no message views, only the four fixed tables (docs/dataset.md)
    empty = tmp_path / "empty.tlog"
    empty.write_bytes(b"")
    status, out, err = cli("sql", "SELECT count(*) FROM HEARTBEAT", str(empty))
    assert status == 2 and out == ""
    last = err.splitlines()[-1]
    assert last.startswith("mavscope: sql: no view HEARTBEAT") and last.endswith(
        "views: anomalies, captures, findings, frames")
    status, _, err = cli("sql", "SELECT count(*) FROM HEARTBEAT JOIN nothing USING (capture_id)", str(SIGNED))
    assert status == 2 and "no view nothing " in err and "HEARTBEAT, " in err


def test_a_damaged_dataset_is_a_one_line_error(cli: Cli, tmp_path: Path) -> None:
    """A Parquet file of the dataset emptied, cut (its footer kept), bit-flipped or replaced by a directory, and
    a manifest that is not JSON: one line naming the table (and the file where DuckDB names it), exit 2; a
    DuckDB traceback before (stop 20)."""
    root = tmp_path / "ds"
    assert cli("export", str(SIGNED), "--parquet", str(root))[0] == 0
    (part,) = (root / "frames").glob("capture_id=*/part-0.parquet")
    data = part.read_bytes()
    flipped = bytearray(data)
    for i in range(200, len(flipped) - 3000, 97):
        flipped[i] ^= 0x5A
    for damage, named in ((b"", part.name), (data[: len(data) // 2] + data[-2000:], None), (bytes(flipped), None),
                          (None, part.name)):
        if damage is None:
            part.unlink()
            part.mkdir()
        else:
            part.write_bytes(damage)
        status, out, err = cli("sql", "SELECT count(*) FROM frames", str(root))
        assert status == 2 and out == "" and err.count("\n") == 1, err
        assert err.startswith("mavscope: sql: cannot read the dataset's frames table: "), err
        assert named is None or named in err, err
    (root / "_mavscope_dataset.json").write_text('{"format":')
    status, _, err = cli("sql", "SELECT 1", str(root))
    assert status == 2 and err.count("\n") == 1 and "not a mavscope dataset manifest (invalid JSON)" in err
