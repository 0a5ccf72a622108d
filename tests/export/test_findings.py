"""The findings table holds the findings of `objects` and `params` too: on the bundled FTP captures, against
the truth files the generator wrote from what it sent (captures/<capture>.truth.json: the scripts it
uploaded, the unsafe paths it listed, the parameter changes it made and which of them turn a protection
off), and row for row the findings those commands report when run alone."""

from __future__ import annotations

import json
from pathlib import Path

from tests.conftest import CAPTURES, Cli
from tests.support.dataset import arrow_table, sha256

KEY = ("--key", "passphrase:mavscope-demo")  # the generator signs the GCS's frames with it (captures/README.md)
FTP = [CAPTURES / "ftp_lua_upload.pcap", CAPTURES / "ftp_params.pcap"]


def truth(path: Path) -> dict:
    return json.loads(path.with_suffix(".truth.json").read_text())


def security_changes(path: Path) -> list[tuple[str, str | None]]:
    """(name, what it turns off) of each change to a security parameter the generator made."""
    timeline = truth(path)["params"]["timeline"]
    if path.name == "ftp_lua_upload.pcap":
        # its truth lists the changes only; by ArduPilot's parameter reference SCR_ENABLE turns Lua scripting
        # on and ARMING_CHECK 0 turns every pre-arm check off
        assert [(e["name"], e["value"]) for e in timeline] == [("SCR_ENABLE", 1), ("ARMING_CHECK", 0)]
        return [("SCR_ENABLE", None), ("ARMING_CHECK", "every pre-arm check")]
    return [(e["name"], e["disables"]) for e in timeline if e["security"]]


def row(f: dict) -> tuple:
    return f["code"], f["severity"], f["message"], list(f["frames"])


def test_objects_and_params_findings_in_the_dataset(cli: Cli, tmp_path: Path) -> None:
    root = tmp_path / "ds"
    status, _, err = cli("export", *map(str, FTP), *KEY, "--parquet", str(root))
    assert status == 0, err
    rows = arrow_table(root, "findings").to_pylist()
    captures = {r["capture_id"]: r for r in arrow_table(root, "captures").to_pylist()}
    for path in FTP:
        mine = [r for r in rows if r["capture_id"] == sha256(path)]
        assert captures[sha256(path)]["finding_count"] == len(mine)
        by_source = {s: sorted(row(r) for r in mine if r["source"] == s) for s in ("objects", "params")}
        for command in ("objects", "params"):
            alone = cli.json(command, str(path), *KEY)["findings"]
            assert by_source[command] == sorted(row(f) for f in alone), command
        # every change the generator made to a security parameter is one finding naming the parameter
        params = [r for r in mine if r["source"] == "params"]
        assert sorted((r["code"], r["message"].split(" parameter ")[1].split()[0]) for r in params) == sorted(
            ("param-protection-disabled" if disables else "param-security-change", name)
            for name, disables in security_changes(path))
        for _, disables in security_changes(path):
            if disables:
                assert sum(r["message"].endswith(f"turns off {disables}") for r in params) == 1
    lua = [r for r in rows if r["capture_id"] == sha256(FTP[0]) and r["source"] == "objects"]
    t = truth(FTP[0])
    scripts = next(r for r in lua if r["code"] == "script-upload")
    unsafe = next(r for r in lua if r["code"] == "object-unsafe-path")
    assert all(p in scripts["message"] for p in t["script_uploads"])
    assert all(repr(p) in unsafe["message"] for p in t["unsafe_paths"])
