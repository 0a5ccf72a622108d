"""Every rule of the shipped pack fires on a capture built to trigger it and stays quiet on its near miss
(tests/support/ruleflows.py: what each case builds is its expected answer), run through `AuditPass` as every
report of the audit's findings runs it."""

from __future__ import annotations

from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.mavlink.dialect import load_dialect
from mavscope.notes import Finding
from mavscope.rules import load_rules
from tests.support.ruleflows import CASES, Capture, pack_findings, write_case

DIALECT = load_dialect([])
PACK = load_rules()


def rule_findings(path: Path) -> dict[str, Finding]:
    """The rule findings of `audit`'s pass over `path` with the shipped pack, by rule id."""
    return {f.rule: f for f in pack_findings(path) if f.rule is not None}


def test_every_rule_of_the_pack_has_a_case_and_a_reference() -> None:
    assert sorted(r.id for r in PACK) == sorted(CASES)
    for r in PACK:
        assert r.references and all(ref.startswith("https://") for ref in r.references), r.id
        assert r.explanation and r.remediation, r.id


@pytest.mark.parametrize("rule", sorted(CASES))
def test_the_rule_fires_on_its_trigger_and_not_on_its_near_miss(rule: str, tmp_path: Path) -> None:
    got = rule_findings(write_case(tmp_path, rule, True))
    assert rule in got, f"{rule} did not fire; fired: {sorted(got)}"
    f = got[rule]
    pack = {r.id: r for r in PACK}[rule]
    assert f.code == "rule" and f.severity is pack.severity and f.frames
    assert f.to_json()["rule"] == rule
    quiet = rule_findings(write_case(tmp_path, rule, False))
    assert rule not in quiet, f"{rule} fired on its near miss: {quiet[rule]}"



@pytest.mark.parametrize(("param1", "fires"), [(float("nan"), True), (-1e10, True), (-3.0, True), (4.0, False)])
def test_a_fence_vertex_count_that_is_not_a_count(param1: float, fires: bool, tmp_path: Path) -> None:
    """ArduPilot issue 31903's fence items: MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION (5001) whose param1 (the
    vertex count) is NaN or negative; 4 vertices is a fence."""
    c = Capture()
    c.send(v2.MAVLink_mission_item_int_message(1, 1, 0, 5, 5001, 0, 1, param1, 0, 0, 0, 473_977_420, 85_455_940, 0,
                                               1))
    got = rule_findings(c.write(tmp_path, "fence"))
    assert ("ardupilot-mission-param1-out-of-range" in got) is fires
