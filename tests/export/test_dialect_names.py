"""Every file name or SQL identifier an export builds from a dialect's or a capture's strings stays where it
belongs (issue 35, item 6 a): a message name with path components is refused when the dialect loads (one
line, exit 2: tests/mavlink/test_dialect_input.py has the rule), and every path the export writes or
removes is confined to its folder, symbolic links followed (export.dataset.inside), so that a crafted
dataset folder cannot send a write or an `rmtree` elsewhere either. Expected outcomes by hand: which file
is refused with which line, and that nothing appears (or disappears) outside the output folder.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from mavscope.errors import DatasetError
from mavscope.export.dataset import inside, open_dataset, tables
from tests.conftest import Cli
from tests.support import flows
from tests.support.flows import T0, write_tlog

pytest.importorskip("pyarrow")
pytest.importorskip("duckdb")


def snapshot(root: Path) -> set[str]:
    """Every path under `root` (what a test checks nothing was added to or removed from)."""
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def capture(folder: Path) -> str:
    s = flows.Sender(1, 1)
    return write_tlog(folder, [(T0, s.pack(flows.heartbeat())), (T0 + 1, s.pack(flows.heartbeat()))])


@pytest.mark.parametrize("name", ["../../x", "/etc/x", "a/b", "..", "C:\\x", "msg=*"])
@pytest.mark.parametrize("command", ["csv", "parquet", "sql"])
def test_a_message_name_with_path_components_writes_nothing_anywhere(tmp_path: Path, cli: Cli, name: str,
                                                                      command: str) -> None:
    work = tmp_path / "work"
    work.mkdir()
    cap = capture(work)
    evil = work / "evil.xml"
    evil.write_text(f'<?xml version="1.0"?>\n<mavlink><messages><message id="60500" name="{name}"><description>d'
                    '</description><field type="uint8_t" name="a">a</field></message></messages></mavlink>\n')
    before = snapshot(tmp_path)
    out = work / "out" / "deep"
    argv = {"csv": ("export", "-T", "csv", "-o", out, cap),
            "parquet": ("export", "--parquet", out, cap),
            "sql": ("sql", "SELECT count(*) FROM frames", cap)}[command]
    got = cli(*argv, "--dialect", evil)
    assert got.status == 2 and got.out == ""
    shown = name.replace("\\", "\\\\")  # the command line shows a backslash escaped (visible)
    assert got.err == (f"mavscope: {evil.resolve()}: cannot load dialect: line 2: message name '{shown}' is not an "
                       "identifier in upper case (A-Z, 0-9, _)\n")
    assert snapshot(tmp_path) == before  # no file anywhere, in the output folder or outside it


@pytest.mark.parametrize("name", ["../x", "/etc/x", "a/b", "..", ".", "", "a\0b", "C:\\x", "C:x"])
def test_inside_takes_one_plain_name(tmp_path: Path, name: str) -> None:
    with pytest.raises(DatasetError):
        inside(tmp_path, name)
    assert inside(tmp_path, "msg=HEARTBEAT", "capture_id=ab") == tmp_path / "msg=HEARTBEAT" / "capture_id=ab"


def test_a_symbolic_link_in_a_dataset_leads_nowhere_outside(tmp_path: Path, cli: Cli) -> None:
    """A dataset folder someone else prepared: its HEARTBEAT table a symbolic link to a folder outside. The
    export refuses in one line; the outside folder is neither written nor emptied."""
    outside = tmp_path / "outside"
    (outside / "capture_id=x").mkdir(parents=True)
    (outside / "capture_id=x" / "keep.txt").write_text("mine")
    data = tmp_path / "ds"
    open_dataset(data, create=True)
    (data / "msg=HEARTBEAT").symlink_to(outside, target_is_directory=True)
    before = snapshot(outside)
    got = cli("export", "--parquet", data, capture(tmp_path))
    assert got.status == 2
    assert got.err.startswith("mavscope: ") and got.err.count("\n") == 1 and "leads outside" in got.err
    assert snapshot(outside) == before and (outside / "capture_id=x" / "keep.txt").read_text() == "mine"


def test_a_folder_no_dialect_can_name_is_no_table(tmp_path: Path, cli: Cli) -> None:
    """`msg=*` (a glob DuckDB would expand over every table's files), `msg=lower`, `_staging`: not tables."""
    data = tmp_path / "ds"
    assert cli("export", "--parquet", data, capture(tmp_path)).status == 0
    written = tables(data)
    assert "msg=HEARTBEAT" in written
    for odd in ("msg=*", "msg=lower", "msg=", "other"):
        os.makedirs(data / odd / "capture_id=0", exist_ok=True)
    assert tables(data) == written
    got = cli("sql", "SELECT count(*) AS n FROM HEARTBEAT", data, "--json")
    assert got.status == 0 and '"n":2' in got.out.replace(" ", "")
