"""Words a hostile capture chose never drive the analyst's terminal, and never vanish as rich markup.

The capture below is made here with pymavlink: STATUSTEXTs carrying an SGR colour, an OSC 8 hyperlink,
BEL, CR, a backspace, a newline followed by text that looks like one of mavscope's own lines, a
right-to-left override (U+202E, as UTF-8), and square brackets that rich would read as markup; a parameter
whose name holds an escape; all sent over UDP between IPv6 link-local addresses ("[fe80::1]:14550" begins
with a letter, so rich took it for a markup tag and printed ":14550"). What the terminal must get instead
is worked out from the strings themselves: Python's repr escapes (\\x1b, \\u202e, \\n).
"""

from __future__ import annotations

import ipaddress
import re
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as apm

from mavscope.output.console import visible
from tests.conftest import Cli
from tests.native.build import ipv6, link, pcap, udp

HOSTILE = [
    b"\x1b[31mRED\x1b]8;;http://e.example\x07click\x1b]8;;\x07",
    b"[bold]b[/bold] [link=http://e.example]L[/link] \x1b[8mhidden",
    b"a\r\x08b\nmavscope: [warn] forged",
    "\u202eevil".encode(),
]
PARAM = b"\x1b[2JWIPE"
ADDR = "fe80::1"
CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202e]")  # whatever reached stdout


def _capture(tmp_path: Path) -> Path:
    mav = apm.MAVLink(None, srcSystem=1, srcComponent=1)
    msgs = [apm.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3)]
    msgs += [apm.MAVLink_statustext_message(6, t, 0, 0) for t in HOSTILE]
    msgs.append(apm.MAVLink_param_value_message(PARAM, 1.5, 9, 1, 0))
    src, dst = ipaddress.IPv6Address(ADDR).packed, ipaddress.IPv6Address("fe80::2").packed
    records = []
    for i, m in enumerate(msgs):
        records.append((1_700_000_000 + i, 0, link("ethernet", ipv6(src, dst, 17, udp(14550, 14551, m.pack(mav))),
                                                   True)))
    path = tmp_path / "hostile_words.pcap"
    path.write_bytes(pcap(records, 1))
    return path


def _clean(out: str) -> None:
    assert not CONTROL.search(out), repr(CONTROL.search(out))
    assert "\nmavscope: [warn] forged" not in out


def test_visible_escapes_what_repr_escapes() -> None:
    """As `repr` writes a string without its quotes: the backslash escaped too (issue 35), so that a real
    ESC and the four characters backslash, x, 1, b never print alike."""
    for s in ["plain", "tab\there", "\x1b[31m", "\u202e", "\x85", "\ud800", "ok é ü 日本", "a\\x1b", "\\"]:
        want = repr(s)[1:-1].replace("\\'", "'")
        assert visible(s) == want
    assert visible("\x1b") == "\\x1b" and visible("\\x1b") == "\\\\x1b"  # by hand: 4 and 5 characters
    assert len(visible("\x1b")) == 4 and len(visible("\\x1b")) == 5
    assert visible("a\nb", keep_newlines=True) == "a\nb"


def test_events_show_the_words_escaped(cli: Cli, tmp_path: Path) -> None:
    status, out, err = cli("events", str(_capture(tmp_path)))
    assert status == 0, err
    _clean(out)
    flat = re.sub(r"\s*│\s*", " ", out)  # cells may fold; the escaped words are whole in the joined lines
    for t in HOSTILE:
        word = visible(t[:50].decode())  # STATUSTEXT.text is char[50]
        assert word.replace(" ", "") in flat.replace(" ", "").replace("\n", ""), word


def test_stats_keep_an_ipv6_endpoint_that_looks_like_markup(cli: Cli, tmp_path: Path) -> None:
    status, out, err = cli("stats", str(_capture(tmp_path)))
    assert status == 0, err
    _clean(out)
    assert f"[{ADDR}]:14550" in out  # the Links table's endpoints and the Conversations table


@pytest.mark.parametrize("options", [(), ("-V",)])
def test_parameter_names_in_summary_lines_and_trees_are_escaped(cli: Cli, tmp_path: Path,
                                                              options: tuple[str, ...]) -> None:
    status, out, err = cli("read", str(_capture(tmp_path)), *options)
    assert status == 0, err
    _clean(out)
    assert "\\x1b[2JWIPE" in out


def test_sql_cells_are_escaped(cli: Cli, tmp_path: Path) -> None:
    pytest.importorskip("duckdb")
    status, out, err = cli("sql", "SELECT text FROM STATUSTEXT", str(_capture(tmp_path)))
    assert status == 0, err
    _clean(out)
    assert "\\x1b[31mRED" in out and "[bold]b[/bold]" in out and "\\u202eevil" in out


def test_commands_make_no_rich_text_of_their_own() -> None:
    """Every rich Text of the commands comes from mavscope.output.console.text (escaped)."""
    root = Path(__file__).resolve().parents[2] / "mavscope"
    offenders = [str(p.relative_to(root)) for p in sorted((root / "commands").glob("*.py"))
                 if re.search(r"\bText\(|rich\.text", p.read_text())]
    assert offenders == []


# A capture's file name is the analyst's input only in part: it may come with evidence from elsewhere.
# It goes into every problem line on stderr and into the header of a parameter file.
NAME = "x\x1b[2J\nmavscope: [warn] forged\u202e.pcap"


@pytest.mark.parametrize("command", [("read",), ("stats",), ("stats", "--json"), ("events",), ("export", "--parquet")])
def test_a_file_name_on_stderr_is_escaped(cli: Cli, tmp_path: Path, command: tuple[str, ...]) -> None:
    from tests.conftest import CAPTURES

    path = tmp_path / NAME
    path.write_bytes((CAPTURES / "damaged.pcap").read_bytes())  # damage: a problem line per kind on stderr
    extra = [str(tmp_path / "ds")] if command[-1] == "--parquet" else []
    status, _out, err = cli(*command[:1], str(path), *command[1:], *extra)
    assert status == 0, err
    assert visible(NAME) in err  # the lines name the file, escaped
    _clean(err)
    assert all(line.startswith("mavscope: ") for line in err.splitlines())
    status, _out, err = cli(*command[:1], str(tmp_path / ("missing" + NAME)), *command[1:], *extra)
    assert status == 2 and err.count("\n") == 1 and visible(NAME) in err  # the error's one line
    _clean(err)


def test_a_file_name_cannot_add_a_line_to_a_parameter_file(cli: Cli, tmp_path: Path) -> None:
    mav = apm.MAVLink(None, srcSystem=1, srcComponent=1)
    entries = [apm.MAVLink_heartbeat_message(2, 3, 0, 0, 4, 3),
               apm.MAVLink_param_value_message(b"FS_GCS_ENABLE", 1, 9, 1, 0)]
    name = "cap\nARMING_CHECK,0\n.tlog"
    path = tmp_path / name
    path.write_bytes(b"".join((1_700_000_000_000_000 + i).to_bytes(8, "big") + m.pack(mav)  # a tlog
                              for i, m in enumerate(entries)))
    for suffix in (".param", ".params"):
        out = tmp_path / ("p" + suffix)
        status, _, err = cli("params", str(path), "--out", str(out))
        assert status == 0, err
        lines = out.read_text().splitlines()
        assert not any(line.startswith("ARMING_CHECK") for line in lines)
        assert f"from {visible(name)}" in "\n".join(lines)
        # pymavlink's loader (MAVProxy's) reads back the one parameter there is
        if suffix == ".param":
            from pymavlink import mavparm

            loaded = mavparm.MAVParmDict()
            loaded.load(str(out), use_excludes=False)
            assert dict(loaded) == {"FS_GCS_ENABLE": 1.0}


def test_a_filter_error_quotes_the_filter_escaped_with_the_caret_under_the_problem(cli: Cli) -> None:
    from tests.conftest import CAPTURES

    status, out, err = cli("read", str(CAPTURES / "px4_sitl_udp.pcap"), "-Y", 'STATUSTEXT.text == "\x1b[31m" && foo')
    assert status == 2 and out == ""
    _clean(err)
    # \x1b shows as 4 characters: "foo" starts 3 columns further right than in the text given
    assert err.splitlines() == ['mavscope: filter error: unknown field "foo"',
                                '  STATUSTEXT.text == "\\x1b[31m" && foo',
                                "  " + " " * 33 + "^~~"]
