"""Rule files: what `rules check` and `audit --rules` say of a file that does not parse, of a key that is
wrong, of a filter that does not compile (its file, its line, the filter's caret), and a user's rule on a real
capture. Line numbers are counted by hand in the texts below."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from mavscope.mavlink.dialect import load_dialect
from mavscope.rules import RuleError, RuleSet, load_rules, read_file
from mavscope.rules.loader import PACK_DIR
from tests.conftest import REAL_CAPTURES, Cli
from tests.support.pymavlink_reader import read_pcap
from tests.support.ruleflows import write_case

GOOD = """\
# a user's rules
[[rule]]
id = "my-heartbeat"
title = "Heartbeat of system 1"
severity = "note"
filter = "HEARTBEAT && mavlink.sysid == 1"
"""


def write(tmp: Path, text: str, name: str = "mine.toml") -> Path:
    p = tmp / name
    p.write_text(text, encoding="utf-8")
    return p


def problems(path: Path) -> list[str]:
    with pytest.raises(RuleError) as got:
        RuleSet(read_file(path), load_dialect([]))
    return got.value.lines()


def test_a_file_that_is_not_toml_names_its_line(tmp_path: Path) -> None:
    p = write(tmp_path, GOOD + 'references = ["a",\n  oops\n]\n')
    (line,) = problems(p)
    assert line.startswith(f"{p}:8: not TOML"), line  # `oops` is on line 8


def test_a_filter_that_does_not_compile_names_the_line_of_its_filter_and_shows_the_caret(tmp_path: Path) -> None:
    text = GOOD + '\n[[rule]]\nid = "typo"\ntitle = "A misspelt field"\nseverity = "warn"\n' \
                  'filter = "HEARTBEAT.bse_mode & 128"\n'
    p = write(tmp_path, text)
    lines = problems(p)
    assert lines[0].startswith(f"{p}:12: rule typo: filter error: unknown field \"HEARTBEAT.bse_mode\""), lines
    assert lines[1] == "  HEARTBEAT.bse_mode & 128"
    assert lines[2] == "  ^~~~~~~~~~~~~~~~~~"  # under the 18 characters of the unknown name


def test_every_wrong_key_is_said_with_its_line(tmp_path: Path) -> None:
    text = """\
[[rule]]
id = "Bad Id"
title = "x"
severity = "critical"
filter = "HEARTBEAT"
colour = "red"

[[rule]]
title = "no id"
severity = "warn"
filter = "HEARTBEAT"
[rule.threshold]
count = 0
window = 5
per = "planet"
[rule.when]
armed = "yes"
"""
    lines = problems(write(tmp_path, text))
    said = {(int(line.split(":")[1]), line.split(": ", 1)[1].split(":")[0]) for line in lines}
    assert {(2, "rule 1"), (4, "rule Bad Id"), (6, "rule Bad Id"), (8, "rule 2"), (13, "rule 2"), (15, "rule 2"),
            (17, "rule 2")} <= said, lines
    assert any("`severity` must be one of note, warn, error" in line for line in lines)
    assert any("unknown key `colour`" in line for line in lines)


def test_a_rule_id_used_twice_is_refused_with_both_places(tmp_path: Path) -> None:
    a, b = write(tmp_path, GOOD, "a.toml"), write(tmp_path, GOOD, "b.toml")
    with pytest.raises(RuleError) as got:
        load_rules([a, b], default=False)
    assert got.value.lines() == [f"{b}:2: rule my-heartbeat: the id is used already ({a}:2)"]


def test_rules_check_says_ok_or_the_problems(cli: Cli, tmp_path: Path) -> None:
    good = write(tmp_path, GOOD, "good.toml")
    status, out, err = cli("rules", "check", str(good))
    assert (status, out, err) == (0, f"{good}: 1 rule, OK\n", "")
    bad = write(tmp_path, GOOD.replace("mavlink.sysid == 1", "mavlink.sysid ==="), "bad.toml")
    status, out, err = cli("rules", "check", str(bad))
    assert status == 2 and out == ""
    assert err.splitlines()[0].startswith(f"mavscope: {bad}:6: rule my-heartbeat: filter error"), err


def test_rules_list_shows_the_pack_as_its_files_say(cli: Cli) -> None:
    """Each rule's id, severity and references, read here from the pack's TOML by tomllib alone."""
    expected = [t for f in sorted(PACK_DIR.glob("*.toml")) for t in tomllib.loads(f.read_text())["rule"]]
    doc = cli.json("rules", "list")
    assert [(r["id"], r["severity"], r["references"]) for r in doc["rules"]] == \
           [(t["id"], t["severity"], t["references"]) for t in expected]
    status, out, _ = cli("rules", "list")
    assert status == 0 and out.endswith(f"{len(expected)} rules\n")
    for t in expected:
        assert f"{t['id']}  [{t['severity']}]  {t['title']}\n" in out
        assert all(f"    {ref}\n" in out for ref in t["references"])


def test_audit_reports_rule_findings_in_json_and_text_and_can_leave_the_pack_out(cli: Cli, tmp_path: Path) -> None:
    cap = write_case(tmp_path, "cmd-flight-termination", True)  # COMMAND_LONG 185 param1 1: record 2
    status, out, _ = cli("audit", str(cap), "--json")
    assert status == 1
    found = [f for f in json.loads(out)["findings"] if f["code"] == "rule"]
    assert [(f["rule"], f["severity"], f["frames"]) for f in found] == [("cmd-flight-termination", "error", [2])]
    status, out, _ = cli("audit", str(cap))
    assert "[error] rule cmd-flight-termination: Flight termination commanded: 1 frame, first from 255/190 " \
           "(frames 2)" in out
    status, out, _ = cli("audit", str(cap), "--no-default-rules", "--json")
    assert not [f for f in json.loads(out)["findings"] if f["code"] == "rule"]


def test_audit_refuses_a_bad_rule_file_before_reading_the_capture(cli: Cli, tmp_path: Path) -> None:
    bad = write(tmp_path, "[[rule]]\nid = 'x'\n")
    status, out, err = cli("audit", str(tmp_path / "no-such-capture.pcap"), "--rules", str(bad))
    assert status == 2 and out == ""
    assert f"{bad}:1: rule x: `title` is missing" in err


REAL = REAL_CAPTURES / "ipal_transcriber_MAVLink.pcap"


@pytest.mark.skipif(not REAL.exists(), reason="../shared/real-captures is absent (a fresh clone)")
def test_a_user_rule_on_a_real_capture(cli: Cli, tmp_path: Path) -> None:
    """A user's rule on BlueOS traffic (ipal_transcriber: a vehicle 1/1, a camera 1/100, a GCS 255/190): every
    HEARTBEAT of system 1, counted by pymavlink's reader."""
    msgs = read_pcap(REAL)
    want = [i + 1 for i, m in enumerate(msgs) if m.name == "HEARTBEAT" and m.src[0] == 1]
    assert want  # (the capture holds some: else this test could not fail)
    rules = write(tmp_path, GOOD)
    doc = cli.json("audit", str(REAL), "--rules", str(rules), "--no-default-rules")
    (f,) = [f for f in doc["findings"] if f["code"] == "rule"]
    assert (f["rule"], f["severity"], len(f["frames"])) == ("my-heartbeat", "note", len(want))
    assert "first from 1/" in f["message"]


def test_a_title_on_two_lines_or_with_control_characters_is_refused(tmp_path: Path) -> None:
    """A title is printed in audit's text lines: a line break or an escape sequence in it could forge a line."""
    for title in ('"two\\nlines"', '"bell\\u0007"', '"bidi\\u202e"'):
        lines = problems(write(tmp_path, GOOD.replace('"Heartbeat of system 1"', title)))
        assert lines == [f"{tmp_path / 'mine.toml'}:4: rule my-heartbeat: `title` must be printable text of at most "
                         "4000 characters on one line"], lines


def test_a_file_named_twice_is_read_once(tmp_path: Path) -> None:
    good = write(tmp_path, GOOD)
    assert [r.id for r in load_rules([good, tmp_path, str(good)], default=False)] == ["my-heartbeat"]
