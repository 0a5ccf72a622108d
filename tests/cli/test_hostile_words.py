"""Every command of the command line, every output form, on a hostile capture and a hostile dialect
(tests/support/hostile.py): no control, format or bidi character of theirs reaches stdout or stderr, none
of their words is read as markup, and the words are shown escaped by the one rule (mavscope.visible: what
`repr` escapes, and the backslash, so that a real ESC and the typed text `\\x1b` differ). Issue 35 items 5
and 6(d).

The commands are taken from the command line's registry (mavscope.cli.COMMANDS): a command added there
and not given its runs below fails `test_every_command_is_walked`. JSON output escapes C0 controls itself
(and carries C1 and bidi characters as they are, as JSON does): for it only C0 controls are checked. The
expected escaped forms are written here by hand from the strings hostile.py builds: ESC as \\x1b, BEL as
\\x07, U+009B as \\x9b, U+202E as \\u202e, CR and LF as \\r and \\n, a backslash doubled; in a summary line
and the detail tree a string value is in quotes (`repr`).
"""

from __future__ import annotations

import io
import re
import socket
import time
from pathlib import Path

import pytest

from mavscope.cli import COMMANDS, Env, main
from tests.conftest import Cli
from tests.native.engines import same
from tests.support import hostile

STATUS = r"\x1b]0;pwned\x07\x1b[31m\x9b\u202e\r\n[blink red]\\x1b"
STATUS2 = r"\x1b]52;c;ZWNobyBwd25lZA==\x07\u2066\u200b\x85x"
FILE_PATH = r"/\x1b]0;pwned\x07/\x1b]52;c;ZWNobyBwd25lZA==\x07/\x9b\u202e\r\n[blink red]/\\x1b.txt"
PARAM = r"[blink red]\x1b[2J"
LABEL = r"Gain\x9b[blink red]\u202e\r"  # (a table may fold the cell at the escaped \n that follows)
UPLOAD = r"/APM/scripts/[blink red]\x9b.lua"
C0 = re.compile("[\x00-\x08\x0b-\x1f]")

# command -> runs: (arguments, where CAP is the capture, DIA the dialect and OUT a fresh directory;
# the strings the output must hold)
RUNS: dict[str, list[tuple[tuple[str, ...], tuple[str, ...]]]] = {
    "read": [(("CAP",), (f"text='{STATUS}'", f"text='{STATUS2}'", f"OpenFileRO '{FILE_PATH}'",
                         f"param_id='{PARAM}'")),
             (("CAP", "--dialect", "DIA", "-V"), (LABEL, f"'{FILE_PATH}'", f"'{STATUS}'")),
             (("CAP", "-x"), ()), (("CAP", "-T", "json"), ()), (("CAP", "-T", "jsonl"), ())],
    "live": [],  # test_live below
    "stats": [(("CAP", "--dialect", "DIA"), ("NAMED_VALUE_FLOAT",)), (("CAP", "--sparklines", "20"), ()),
              (("CAP", "--json"), ())],
    "mission": [(("CAP",), ()), (("CAP", "--json"), ())],
    "commands": [(("CAP", "--dialect", "DIA"), (LABEL,)), (("CAP", "--json"), ())],
    "timeline": [(("CAP",), ()), (("CAP", "--json"), ())],
    "objects": [(("CAP",), (FILE_PATH, UPLOAD)), (("CAP", "--json"), ()), (("CAP", "--out", "OUT/objects"), ())],
    "params": [(("CAP",), (PARAM,)), (("CAP", "--json"), ()), (("CAP", "--out", "OUT/p.param"), ())],
    "events": [(("CAP", "--dialect", "DIA"), (STATUS, STATUS2, f"'{PARAM}'", f"'{FILE_PATH}'")),
               (("CAP", "--json"), ())],
    "track": [(("CAP", "--json"), ()), (("CAP", "--geojson", "OUT/t.geojson"), ())],
    "plot": [(("CAP", "NAMED_VALUE_FLOAT.value"), ()), (("CAP", "NAMED_VALUE_FLOAT.value", "--json"), ())],
    "report": [(("CAP", "--dialect", "DIA", "-o", "OUT/r.html", "--json", "OUT/r.json"), ())],
    "tui": [],  # tests/tui/test_hostile_screens.py walks every screen
    "verify": [(("CAP", "--key", "hex:" + "00" * 32), ()), (("CAP", "--key", "hex:" + "00" * 32, "--json"), ())],
    "audit": [(("CAP", "--dialect", "DIA"), ()), (("CAP", "--json"), ())],
    "rules": [(("list", "--dialect", "DIA"), ()), (("list", "--json"), ())],  # (the pack against the dialect)
    "export": [(("CAP", "--parquet", "OUT/ds"), ()), (("CAP", "-T", "csv", "-o", "OUT/csv"), ()),
               (("CAP", "--parquet", "OUT/ds", "--json"), ())],
    "sql": [(("SELECT text FROM STATUSTEXT", "CAP"), (STATUS, STATUS2)),
            (("SELECT param_id FROM PARAM_VALUE", "CAP", "--csv"), ()),
            (("SELECT text FROM STATUSTEXT", "CAP", "--json"), ())],
    "batch": [(("CAP", "--", "stats"), ()), (("CAP", "--", "audit"), ()), (("CAP", "--json", "--", "stats"), ())],
}
ELSEWHERE = {"tui": "tests/tui/test_hostile_screens.py", "live": "test_live"}


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    tmp = tmp_path_factory.mktemp("hostile")
    return hostile.write_capture(tmp), hostile.write_dialect(tmp), tmp


def _clean(out: str, json_out: bool) -> None:
    bad = (C0 if json_out else hostile.RAW).search(out)
    assert bad is None, (bad.group(), out[max(0, bad.start() - 60) : bad.end() + 60])


def test_every_command_is_walked() -> None:
    assert set(RUNS) == set(COMMANDS), "give a new command its runs here"
    assert all(RUNS[c] or c in ELSEWHERE for c in COMMANDS)


RUN_IDS = [(c, i) for c, runs in RUNS.items() for i in range(len(runs))]


@pytest.mark.parametrize(("command", "i"), RUN_IDS, ids=[f"{c}-{i}" for c, i in RUN_IDS])
def test_command_shows_hostile_words_escaped(command: str, i: int, files: tuple[Path, Path, Path],
                                             tmp_path: Path) -> None:
    cap, dia, _ = files
    argv, wanted = RUNS[command][i]
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    words = [a.replace("CAP", str(cap)).replace("DIA", str(dia)).replace("OUT", str(out_dir)) for a in argv]
    status, out, err = Cli({"COLUMNS": "1000"})(command, *words)
    assert status in (0, 1), err
    data = "--csv" in argv  # CSV to a file or a pipe: the exact values (test_sql_csv_on_a_terminal)
    json_out = "--json" in argv or "json" in argv or "jsonl" in argv
    if not data:
        _clean(out, json_out)
    _clean(err, False)
    assert "\x1b" not in (err if data else out + err)
    for w in wanted:
        assert w in out, (w, out[:2000])


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_sql_csv_on_a_terminal(files: tuple[Path, Path, Path]) -> None:
    """`sql --csv` writes the exact values to a file or a pipe, and to a terminal every cell escaped."""
    pytest.importorskip("duckdb")
    cap, _, _ = files
    out, err = _Terminal(), io.StringIO()
    status = main(["sql", "SELECT text FROM STATUSTEXT", str(cap), "--csv"], Env(stdout=out, stderr=err, environ={}))
    assert status == 0, err.getvalue()
    _clean(out.getvalue(), False)
    assert out.getvalue().splitlines() == ["text", STATUS, STATUS2]  # (no comma or quote: no CSV quoting)
    piped = Cli()("sql", "SELECT text FROM STATUSTEXT", str(cap), "--csv")
    assert hostile.STATUS.split("\r")[0] in piped.out  # the exact value, up to its CR (CSV quotes a CR/LF)


def test_live(files: tuple[Path, Path, Path]) -> None:
    """`live` prints as `read` does (output/printer.py): the hostile frames sent to its port, in summary
    lines and in the -V tree."""
    from tests.live.test_live import LiveRun

    cap, dia, _ = files
    frames = [frame for _t, frame in hostile.hostile_flow().entries]
    for extra in ((), ("-V", "--dialect", str(dia))):
        run = LiveRun("--udp", "127.0.0.1:0", "-c", str(len(frames)), "--duration", "20", *extra)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for frame in frames:
                s.sendto(frame, ("127.0.0.1", run.port))
                time.sleep(0.001)
        status, out, err = run.join(30)
        assert status == 0, err
        _clean(out, False)
        _clean(err, False)
        assert f"text='{STATUS}'" in out
        if extra:
            assert LABEL in out


@pytest.mark.parametrize("fmt", [(), ("-T", "jsonl")], ids=["summary", "jsonl"])
@pytest.mark.parametrize("with_dialect", [False, True], ids=["default", "dialect"])
def test_both_engines_read_the_hostile_capture_alike(fmt: tuple[str, ...], with_dialect: bool, cli: Cli,
                                                     files: tuple[Path, Path, Path]) -> None:
    pytest.importorskip("mavscope._native", reason="the native extension is not built")
    cap, dia, _ = files
    extra = ("--dialect", str(dia)) if with_dialect else ()
    result = same(cli, cap, *extra, fmt=fmt)
    if not fmt:
        assert f"text='{STATUS}'" in result.out


@pytest.mark.parametrize("with_dialect", [False, True], ids=["default", "dialect"])
def test_both_engines_stats_alike(with_dialect: bool, cli: Cli, files: tuple[Path, Path, Path]) -> None:
    pytest.importorskip("mavscope._native", reason="the native extension is not built")
    cap, dia, _ = files
    extra = ("--dialect", str(dia)) if with_dialect else ()
    for form in ((), ("--json",)):
        p = cli("stats", str(cap), *extra, *form, environ={"MAVSCOPE_PURE": "1"})
        n = cli("stats", str(cap), *extra, *form, environ={})
        assert (n.status, n.out, n.err) == (p.status, p.out, p.err)
