"""`mavscope batch`: each capture's result is the command's own (run alone through the CLI), the exit
status the worst of them (2 > 1 > 0), in one process or in worker processes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import mavscope.commands.batch as batch_mod
from tests.conftest import CAPTURES, Cli

KEY = ("--key", "passphrase:mavscope-demo")  # signed_udp.pcap's (captures/README.md)
SOME = [CAPTURES / n for n in ("signed_udp.pcap", "key_exchange_udp.pcap", "px4_sitl_udp.pcap")]


def _alone(cli: Cli, command: str, path: Path, *args: str) -> tuple[int, dict]:
    status, out, err = cli(command, str(path), *args, "--json")
    assert status in (0, 1), err
    return status, json.loads(out)


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_verify_over_captures_as_each_alone(cli: Cli, jobs: str) -> None:
    status, out, err = cli("batch", *map(str, SOME), "-j", jobs, "--json", "--", "verify", *KEY)
    assert err == ""
    doc = json.loads(out)
    alone = [_alone(cli, "verify", p, *KEY) for p in SOME]
    assert [c["file"] for c in doc["captures"]] == [str(p) for p in SOME]
    assert [(c["exit"], c["result"]) for c in doc["captures"]] == alone
    # key_exchange_udp.pcap's frames are signed with keys this passphrase does not give: verify fails
    assert [s for s, _ in alone] == [0, 1, 0]
    assert status == doc["exit"] == 1 and doc["status"] == "findings"


def test_a_directory_text_summary_and_stats(cli: Cli) -> None:
    # the capture column folds a path longer than a third of the width: wide enough for the longest capture
    # path of this clone (sized by stats_loss.pcap alone, key_exchange_udp.pcap folded under /tmp/tmp.*)
    wide = {"COLUMNS": str(max(160, 3 * max(len(str(p)) for p in CAPTURES.iterdir())))}
    status, out, err = cli("batch", str(CAPTURES), "--", "stats", environ=wide)
    # by name: README.md, expected.json and the generator's *.truth.json are not captures (batch sniffs content)
    files = [p for p in CAPTURES.iterdir() if p.is_file()]
    captures = [p for p in files if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw")]
    assert f"{len(files) - len(captures)} file(s) in the directories are not captures" in err
    stats = cli.json("stats", str(CAPTURES / "stats_loss.pcap"))["totals"]
    line = next(ln for ln in out.splitlines() if "stats_loss.pcap" in ln)
    assert f"{stats['links']} link(s), {stats['lost']} lost" in line and str(stats["frames"]) in line
    # stats exits 0 whatever it finds: a capture with findings is "findings" all the same, and so is the batch
    found = sum(any(f["severity"] in ("warn", "error") for f in cli.json("stats", str(p))["findings"])
                for p in captures)  # (audit's rule: notes are information)
    assert 0 < found < len(captures) and status == 1
    assert all(any(str(p) in ln for ln in out.splitlines()) for p in captures)  # every path whole on a line
    # damaged.pcap's cut record (captures/README.md) and px4_sitl_tcp.pcap's retransmission, noted on its own
    # record (tshark: frame 148 is tcp.analysis.retransmission, 52 bytes)
    assert (f"{len(captures) - found} ok, {found} with findings, 0 error(s); 2 with problems on stderr; "
            "exit status 1 (findings)") in out


def test_stats_findings_decide_the_status(cli: Cli) -> None:
    # gcs_takeover.pcap: an intruder GCS disarms the vehicle in the air (gcs_takeover.truth.json: in-flight-disarm)
    takeover = CAPTURES / "gcs_takeover.pcap"
    assert "in-flight-disarm" in json.loads((CAPTURES / "gcs_takeover.truth.json").read_text())["findings"]
    status, out, _ = cli("batch", str(takeover), str(SOME[0]), "--json", "--", "stats")
    rows = json.loads(out)["captures"]
    assert status == 1 and [(r["status"], r["exit"]) for r in rows] == [("findings", 1), ("ok", 0)]
    assert "1 error" in rows[0]["summary"] and "[in-flight-disarm]" in rows[0]["summary"]


def test_notes_alone_leave_a_capture_ok(cli: Cli, real_captures: Path) -> None:
    # px4_fw_mission_download_raw.bin (PX4 over serial) has one note-severity finding, seq-reordered, and no
    # other; a note is information: the capture is ok, as audit would exit 0
    real = real_captures / "px4_fw_mission_download_raw.bin"
    severities = {f["severity"] for f in cli.json("stats", str(real))["findings"]}
    assert severities == {"note"}
    status, out, _ = cli("batch", str(real), "--json", "--", "stats")
    (row,) = json.loads(out)["captures"]
    assert (status, row["status"]) == (0, "ok") and "1 note" in row["summary"]


def test_worst_status_with_an_error(cli: Cli, monkeypatch: pytest.MonkeyPatch) -> None:
    real = batch_mod.run_one

    def one_fails(argv: list[str], environ: dict[str, str]) -> tuple[int, str, str]:
        if argv[1].endswith("px4_sitl_udp.pcap"):
            return 2, "", "mavscope: px4_sitl_udp.pcap: cannot read: Input/output error\n"
        return real(argv, environ)

    monkeypatch.setattr(batch_mod, "run_one", one_fails)
    status, out, _ = cli("batch", *map(str, SOME), "--json", "--", "verify", *KEY)
    doc = json.loads(out)
    assert status == doc["exit"] == 2 and [c["status"] for c in doc["captures"]] == ["ok", "findings", "error"]
    assert doc["captures"][2]["summary"] == "px4_sitl_udp.pcap: cannot read: Input/output error"


def test_every_run_refused_and_usage(cli: Cli) -> None:
    status, out, _ = cli("batch", str(SOME[0]), "--", "stats", "-Y", "mavlink.seq ==")
    assert status == 2 and "error" in out
    for argv, message in ((("batch", str(SOME[0])), "give the command after --"),
                          (("batch", str(SOME[0]), "--", "read"), "runs verify, audit, stats")):
        status, _, err = cli(*argv)
        assert status == 2 and message in err


def test_a_long_path_stays_whole_where_it_takes_a_third_of_the_width(cli: Cli, tmp_path: Path) -> None:
    """Piped output is 160 columns wide ($COLUMNS otherwise): a 50-character path was folded at 32 to give
    the summary and problems columns room."""
    deep = tmp_path / ("d" * max(1, 50 - len(str(tmp_path)) - len("/x.pcap") - 1))
    deep.mkdir()
    path = deep / "x.pcap"
    path.write_bytes((CAPTURES / "stats_loss.pcap").read_bytes())
    width = max(160, 3 * len(str(path)))
    _, out, _ = cli("batch", str(path), str(CAPTURES / "damaged.pcap"), "--", "stats", environ={"COLUMNS": str(width)})
    assert any(str(path) in ln for ln in out.splitlines())
    _, narrow, _ = cli("batch", str(path), "--", "stats", environ={"COLUMNS": "60"})
    assert all(len(ln) <= 60 for ln in narrow.splitlines())  # folded, never wider than asked
    assert "".join(ln.split("│")[1].strip() for ln in narrow.splitlines() if ln.startswith("│")).startswith(str(path))
