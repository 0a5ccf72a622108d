"""The engine's parts: which frames a filter can match (the prefilter, never narrower than the filter), the
threshold per sender and its bound, and the conditions' vehicle and link state. Expected values by hand:
message ids from MAVLink's common.xml (HEARTBEAT 0, ATTITUDE 30, COMMAND_INT 75, COMMAND_LONG 76,
FILE_TRANSFER_PROTOCOL 110), thresholds from the frames each test builds."""

from __future__ import annotations

from pathlib import Path

import pytest

from mavscope.fields.registry import FieldRegistry
from mavscope.filter import compile_filter
from mavscope.mavlink.dialect import load_dialect
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import open_session
from mavscope.rules import RuleEngine, RuleSet, engine
from mavscope.rules.loader import read_text
from mavscope.rules.prefilter import filter_scope
from tests.conftest import CAPTURES
from tests.support.builders import command_long_msg
from tests.support.ruleflows import GCS, Capture

DIALECT = load_dialect([])
REGISTRY = FieldRegistry(DIALECT)


@pytest.mark.parametrize(("text", "ids", "signed"), [
    ("HEARTBEAT", {0}, False),
    ("COMMAND_LONG.command == 20", {76}, False),
    ("(COMMAND_LONG || COMMAND_INT) && command == 400", {75, 76}, False),
    ("HEARTBEAT || ATTITUDE", {0, 30}, False),
    ("mavlink.msgid in {0 30}", {0, 30}, False),
    ("mavlink.msgname == ATTITUDE && mavlink.sysid == 1", {30}, False),
    ("not HEARTBEAT", None, False),
    ("HEARTBEAT || mavlink.sysid == 1", None, False),
    ("ftp.opcode == 3", {110}, False),
    ("signature.timestamp > 5", None, True),
    ("signature || HEARTBEAT", None, False),
    ("HEARTBEAT && signature", {0}, True),
])
def test_the_scope_of_a_filter(text: str, ids: set[int] | None, signed: bool) -> None:
    scope = filter_scope(text, REGISTRY)
    assert (None if scope.messages is None else set(scope.messages), scope.signed) == (ids, signed)


FILTERS = ["HEARTBEAT", "command == 400", "(COMMAND_LONG || COMMAND_INT) && param1 > 0", "x > 0 && not ATTITUDE",
           "mavlink.msgid in {0..40}", "ftp.opcode == OpenFileRO", "signature.link_id >= 0", "seq == 1",
           "PARAM_SET.param_id contains \"FENCE\" || mavlink.msgname == MISSION_COUNT"]


@pytest.mark.parametrize("capture", ["signed_udp.pcap", "ftp_params.pcap", "commands_ack.pcap"])
def test_no_frame_outside_its_scope_matches_a_filter(capture: str) -> None:
    """The prefilter is never narrower than the filter: on every frame of three bundled captures, a frame the
    compiled filter matches is in the filter's scope."""
    flts = [(compile_filter(t, DIALECT, REGISTRY), filter_scope(t, REGISTRY)) for t in FILTERS]
    with open_session(str(CAPTURES / capture), PipelineOptions(), dialect=DIALECT) as session:
        for f in session.items:
            if type(f) is Anomaly:
                continue
            for flt, scope in flts:
                if flt.matches(f):
                    assert scope.messages is None or f.msgid in scope.messages, (flt.text, f.record)
                    assert not scope.signed or f.signature is not None, (flt.text, f.record)


def run(rules_text: str, c: Capture, tmp: Path) -> RuleEngine:
    eng = RuleEngine(RuleSet(read_text("t.toml", rules_text), DIALECT))
    with open_session(str(c.write(tmp, "t")), PipelineOptions(), dialect=DIALECT) as session:
        for f in session.items:
            if type(f) is not Anomaly:
                eng.add(f)
    return eng


THRESHOLD = """\
[[rule]]
id = "rtl-burst"
title = "RTL burst"
severity = "warn"
filter = "COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH"
[rule.threshold]
count = 3
window = 1.0
per = "sender"
"""


def test_a_threshold_counts_per_sender_within_its_window(tmp_path: Path) -> None:
    c = Capture()  # frames 0.1 s apart (records 1..)
    for _ in range(3):
        c.send(command_long_msg(20), GCS)  # records 1-3: three within 0.2 s: fires at record 3
    for _ in range(2):
        c.send(command_long_msg(20), (254, 1))  # records 4-5: two from another sender: not enough
    for _ in range(3):
        c.t += 2.0
        c.send(command_long_msg(20), GCS)  # records 6-8: three, 2.1 s apart: never three within 1 s
    (f,) = run(THRESHOLD, c, tmp_path).findings()
    assert (f.rule, f.frames) == ("rtl-burst", (3,))
    assert "1 time (at least 3 matches within 1 s per sender)" in f.message


def test_a_flood_of_senders_is_bounded_and_said_as_capacity(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(engine, "MAX_KEYS", 4)
    c = Capture()
    c.send(command_long_msg(20), GCS)  # the established sender's first match
    for sysid in range(10, 20):  # ten made-up senders, one match each: a bound of 4 gives up 7
        c.send(command_long_msg(20), (sysid, 1))
    c.send(command_long_msg(20), GCS)
    c.send(command_long_msg(20), GCS)  # records 12, 13: the established sender's count was kept: fires at 13
    findings = run(THRESHOLD.replace("window = 1.0", "window = 10.0"), c, tmp_path).findings()
    hits = [f for f in findings if f.code == "rule"]
    capacity = [f for f in findings if f.code == "capacity"]
    assert [f.frames for f in hits] == [(13,)]
    assert len(capacity) == 1 and "7 given up" in capacity[0].message


ARMED = """\
[[rule]]
id = "armed-rtl"
title = "RTL to an armed vehicle in LOITER"
severity = "note"
filter = "COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH"
[rule.when]
armed = true
mode = "loiter"
"""


def test_vehicle_conditions_follow_the_heartbeats(tmp_path: Path) -> None:
    c = Capture()
    c.send(command_long_msg(20))  # record 1: no HEARTBEAT yet: no vehicle state, no match
    c.vehicle(False)
    c.send(command_long_msg(20))  # record 3: disarmed
    c.vehicle(True)
    c.send(command_long_msg(20))  # record 5: armed, LOITER
    c.vehicle(True, mode=3)
    c.send(command_long_msg(20))  # record 7: armed, AUTO
    (f,) = run(ARMED, c, tmp_path).findings()
    assert f.frames == (5,)
