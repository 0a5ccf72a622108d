"""The dataset on disk: re-runs skip captures already there (by content), a capture is in the dataset
only once all its tables are (a crash at any point leaves nothing a query or the skip trusts), the
layout is Hive partitioning by capture id, and datasets of another schema version are refused."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

import mavscope.export.dataset as dataset_mod
import mavscope.export.run as run_mod
from mavscope.errors import CaptureError
from tests.conftest import CAPTURES, Cli
from tests.support.dataset import arrow_table, sha256

A, B = CAPTURES / "px4_sitl_udp.pcap", CAPTURES / "signed_udp.pcap"


def _export(cli: Cli, root: Path, *paths: Path) -> dict:
    status, out, err = cli("export", *map(str, paths), "--parquet", str(root), "--json")
    assert status == 0, err
    return json.loads(out)


def _files(root: Path) -> dict[str, float]:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in root.rglob("*.parquet")}


def test_layout_and_rerun_skips_by_content(cli: Cli, tmp_path: Path) -> None:
    root = tmp_path / "ds"
    first = _export(cli, root, A)
    assert [c["status"] for c in first["captures"]] == ["exported"]
    cid = sha256(A)
    assert first["captures"][0]["capture_id"] == cid
    assert (root / "frames" / f"capture_id={cid}" / "part-0.parquet").is_file()
    assert (root / "msg=HEARTBEAT" / f"capture_id={cid}" / "part-0.parquet").is_file()
    assert json.loads((root / "_mavscope_dataset.json").read_text())["schema_version"] == 1
    before = _files(root)
    # the same content under another name is the same capture; a new one is added
    copy = tmp_path / "copy.pcap"
    shutil.copyfile(A, copy)
    second = _export(cli, root, copy, B)
    assert [(c["path"], c["status"]) for c in second["captures"]] == [(str(copy), "skipped"), (str(B), "exported")]
    assert {k: v for k, v in _files(root).items() if k in before} == before  # untouched
    assert sorted(arrow_table(root, "captures").column("capture_id").to_pylist()) == sorted([cid, sha256(B)])
    # twice in one run: exported once
    third = _export(cli, tmp_path / "ds2", A, copy)
    assert [c["status"] for c in third["captures"]] == ["exported", "duplicate"]


def test_replace_exports_again(cli: Cli, tmp_path: Path) -> None:
    root = tmp_path / "ds"
    _export(cli, root, A)
    status, out, _ = cli("export", str(A), "--parquet", str(root), "--replace", "--json")
    assert status == 0 and json.loads(out)["captures"][0]["status"] == "exported"
    assert arrow_table(root, "frames").num_rows == 1371


def test_a_crash_before_the_commit_leaves_nothing_trusted(cli: Cli, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    root = tmp_path / "ds"
    real_replace = os.replace

    def crash_on_captures(src: object, dst: object) -> None:
        if "captures" in Path(str(dst)).parts[-2:-1]:
            raise KeyboardInterrupt  # the process dies between renaming the tables and the commit
        real_replace(src, dst)  # type: ignore[arg-type]

    monkeypatch.setattr(dataset_mod.os, "replace", crash_on_captures)
    assert cli("export", str(A), "--parquet", str(root)).status == 130  # interrupted
    monkeypatch.setattr(dataset_mod.os, "replace", real_replace)
    cid = sha256(A)
    assert (root / "frames" / f"capture_id={cid}").is_dir()  # a table made it, the commit did not
    assert not list((root / "_staging").iterdir())
    # queries see no part of it
    status, out, err = cli("sql", "SELECT count(*) AS n FROM frames", str(root), "--json")
    assert status == 0 and json.loads(out) == [{"n": 0}], err
    # and the next export does not skip it
    again = _export(cli, root, A)
    assert again["captures"][0]["status"] == "exported"
    assert arrow_table(root, "frames").num_rows == 1371


def test_a_killed_export_leaves_staging_and_orphans_the_next_run_clears(cli: Cli, tmp_path: Path) -> None:
    root = tmp_path / "ds"
    _export(cli, root, B)
    cid = sha256(A)
    # what SIGKILL in the middle of a write leaves: a staging folder, and a table renamed without commit
    (root / "_staging" / f"{cid}.dead" / "frames").mkdir(parents=True)
    orphan = root / "frames" / f"capture_id={cid}"
    orphan.mkdir()
    shutil.copyfile(next((root / "frames").glob("capture_id=*/part-0.parquet")), orphan / "part-0.parquet")
    assert _export(cli, root, A)["captures"][0]["status"] == "exported"
    assert not list((root / "_staging").iterdir())
    assert arrow_table(root, "frames", cid).num_rows == 1371  # not 1371 + the orphan's rows


def test_an_unreadable_capture_fails_alone(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    root = tmp_path / "ds"
    gone = tmp_path / "gone.pcap"
    gone.write_bytes(A.read_bytes())
    real_id = run_mod.content_id

    def unreadable(path: str) -> str:
        if path == str(gone):  # as a capture on a failing disk, or one the user may not read
            raise CaptureError("cannot read: Input/output error", path=path)
        return real_id(path)

    monkeypatch.setattr(run_mod, "content_id", unreadable)
    status, out, err = cli("export", str(gone), str(B), "--parquet", str(root))
    assert status == 2 and err == f"mavscope: {gone}: cannot read: Input/output error\n"
    assert "exported 1 capture(s)" in out and "1 failed" in out


def test_other_versions_and_non_datasets_are_refused(cli: Cli, tmp_path: Path) -> None:
    root = tmp_path / "ds"
    _export(cli, root, B)
    manifest = root / "_mavscope_dataset.json"
    doc = json.loads(manifest.read_text())
    manifest.write_text(json.dumps({**doc, "schema_version": 99}))
    for argv in (("export", str(A), "--parquet", str(root)), ("sql", "SELECT 1", str(root))):
        status, _, err = cli(*argv)
        assert status == 2 and err.count("\n") == 1, err
        assert "schema version 99" in err and "version 1" in err and "new directory" in err
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    status, _, err = cli("export", str(A), "--parquet", str(other))
    assert status == 2 and "not a mavscope dataset" in err
    assert (other / "notes.txt").read_text() == "mine" and len(list(other.iterdir())) == 1


def test_usage_errors(cli: Cli, tmp_path: Path) -> None:
    for argv, message in (
        (("export", str(A)), "no output"),
        (("export", str(A), "-T", "csv", "--parquet", str(tmp_path / "x")), "with -T csv give -o DIR"),
        (("export", str(A), "--parquet", str(tmp_path / "x"), "--scheduler", "tcp://h:1"), "needs --engine dask"),
        (("export", str(tmp_path / "missing.pcap"), "--parquet", str(tmp_path / "x")), "no such file"),
        (("export", str(A), "--parquet", str(tmp_path / "x"), "-j", "0"), "whole positive number"),
    ):
        status, out, err = cli(*argv)
        assert status == 2 and message in err and err.count("\n") == 1, (argv, err)
    assert not (tmp_path / "x").exists()
    for bad in ("²", "0", "-1", "x"):  # '²'.isdigit() is True, int('²') fails
        for argv in (("export", str(A), "--parquet", str(tmp_path / "x"), "-j", bad),
                     ("batch", str(A), "-j", bad, "--", "stats")):
            status, _, err = cli(*argv)
            assert status == 2 and "whole positive number" in err, (argv, err)
