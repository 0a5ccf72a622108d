"""Display filters: counts for each operator and name form on captures whose truth is known
(captures/expected.json lists every frame's record, sysid, compid, seq and msgid), error positions,
and the `read -Y` entry point."""

from __future__ import annotations

import json
from collections import Counter

import pytest

from mavscope.capture.detect import open_capture
from mavscope.filter import FilterError, compile_filter
from mavscope.filter.parser import parse
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import CAPTURES, Cli

EXPECTED = json.loads((CAPTURES / "expected.json").read_text())
UDP = EXPECTED["px4_sitl_udp.pcap"]["frame_list"]  # [record, index, sysid, compid, seq, msgid]
MSGIDS = Counter(f[5] for f in UDP)


@pytest.fixture(scope="module")
def frames(dialect: Dialect) -> list[Frame]:
    with open_capture(CAPTURES / "px4_sitl_udp.pcap") as r:
        return [f for f in Dissector(dialect).run(r) if type(f) is not Anomaly]


def count(frames: list[Frame], text: str, dialect: Dialect) -> int:
    flt = compile_filter(text, dialect)
    return sum(1 for f in frames if flt.matches(f))


def truth(pred) -> int:  # type: ignore[no-untyped-def]
    return sum(1 for f in UDP if pred(*f))


@pytest.mark.parametrize("text, expected", [
    # header names, Wireshark Lua aliases, and their comparisons
    ("mavlink_proto.msgid == 73", MSGIDS[73]),
    ("mavlink.msgid == 73", MSGIDS[73]),
    ("mavlink.msgid eq 0x49", MSGIDS[73]),
    ("mavlink.msgid == MISSION_ITEM_INT", MSGIDS[73]),
    ("mavlink_proto.sysid == 255", truth(lambda r, i, s, c, q, m: s == 255)),
    ("mavlink.sysid != 255", truth(lambda r, i, s, c, q, m: s != 255)),
    ("mavlink_proto.sequence < 10", truth(lambda r, i, s, c, q, m: q < 10)),
    ("mavlink.seq <= 10", truth(lambda r, i, s, c, q, m: q <= 10)),
    ("mavlink.seq > 250", truth(lambda r, i, s, c, q, m: q > 250)),
    ("mavlink.seq >= 250", truth(lambda r, i, s, c, q, m: q >= 250)),
    ("mavlink.msgid in {0 30 33}", truth(lambda r, i, s, c, q, m: m in (0, 30, 33))),
    ("mavlink.msgid in {0, 30..33}", truth(lambda r, i, s, c, q, m: m == 0 or 30 <= m <= 33)),
    ("frame.number <= 100", truth(lambda r, i, s, c, q, m: r <= 100)),
    ("frame.index == 2", truth(lambda r, i, s, c, q, m: i == 2)),
    # bare message names, payload names, enum names
    ("HEARTBEAT", MSGIDS[0]),
    ("!HEARTBEAT", len(UDP) - MSGIDS[0]),
    ("not HEARTBEAT and not ATTITUDE", len(UDP) - MSGIDS[0] - MSGIDS[30]),
    ("HEARTBEAT || ATTITUDE", MSGIDS[0] + MSGIDS[30]),
    ("(HEARTBEAT or ATTITUDE) && mavlink.sysid == 1", truth(lambda r, i, s, c, q, m: s == 1 and m in (0, 30))),
    ("HEARTBEAT.type == MAV_TYPE_QUADROTOR", truth(lambda r, i, s, c, q, m: s == 1 and m == 0)),
    ("HEARTBEAT.type == MAV_TYPE_GCS", truth(lambda r, i, s, c, q, m: s == 255 and m == 0)),
    ("type == MAV_TYPE_GCS", truth(lambda r, i, s, c, q, m: s == 255 and m == 0)),
    ("COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH", 1),
    ("COMMAND_LONG.command == 20", 1),
    ("mavlink_proto.COMMAND_LONG_command == 20", 1),
    ("command == MAV_CMD_NAV_RETURN_TO_LAUNCH", 3),  # COMMAND_LONG, its COMMAND_ACK, mission item 3
    ("COMMAND_ACK", MSGIDS[77]),
    ("COMMAND_ACK.result == MAV_RESULT_ACCEPTED", MSGIDS[77]),
    ("COMMAND_ACK.result != MAV_RESULT_ACCEPTED", 0),
    ("MISSION_ITEM_INT.x > 473977419", 2),  # the two waypoints north of home
    ("MISSION_ITEM_INT.seq in {1..2}", 2),
    ("HEARTBEAT.base_mode & MAV_MODE_FLAG_SAFETY_ARMED", None),
    # strings, regexes, verdicts
    ('STATUSTEXT.text contains "RTL"', 1),
    ('STATUSTEXT.text matches "^(Armed|Disarmed)"', 2),
    ("STATUSTEXT.text ~ \"ed$\"", 2),
    ("mavlink.crc_status == ok", len(UDP)),
    ('crc_status == "bad"', 0),
    ("mavlink.msgname == HEARTBEAT", MSGIDS[0]),
    ("signature", 0),
    ("mavlink.version == 2", len(UDP)),
    # addresses and ports
    ("ip.src == 127.0.0.1", len(UDP)),
    ("ip.dst == 10.0.0.0/8", 0),
    ("udp.srcport == 14550", truth(lambda r, i, s, c, q, m: s == 255)),
    ("udp.port == 14550", len(UDP)),
    ("udp.dstport != 14550", truth(lambda r, i, s, c, q, m: s == 255)),
    ("tcp.port == 5760", 0),
])
def test_filter_counts(frames: list[Frame], dialect: Dialect, text: str, expected: int | None) -> None:
    n = count(frames, text, dialect)
    if expected is not None:
        assert n == expected, text
    else:
        assert 0 < n < MSGIDS[0]


def test_mission_item_coordinates(frames: list[Frame], dialect: Dialect) -> None:
    # takeoff at home (x = 473977419), WP1 and WP2 north of home, RTL at 0
    assert count(frames, "MISSION_ITEM_INT.x == 473977419", dialect) == 1
    assert count(frames, "MISSION_ITEM_INT.x == 0", dialect) == 1


def test_absent_field_makes_every_comparison_false(frames: list[Frame], dialect: Dialect) -> None:
    n_cmd = count(frames, "COMMAND_LONG", dialect)
    # != on a field the frame lacks is false too: only COMMAND_LONG frames can match
    assert count(frames, "COMMAND_LONG.command != 0", dialect) == n_cmd
    assert count(frames, "not COMMAND_LONG.command == 0", dialect) == len(UDP)
    assert count(frames, "udp.srcport != 1", dialect) == len(UDP)
    assert count(frames, "signature.status != valid", dialect) == 0


def test_tlog_and_tcp_names(dialect: Dialect) -> None:
    with open_capture(CAPTURES / "px4_sitl_tcp.pcap") as r:
        tcp = [f for f in Dissector(dialect).run(r) if type(f) is not Anomaly]
    assert sum(compile_filter("tcp.port == 5760", dialect).matches(f) for f in tcp) == len(tcp)
    assert sum(compile_filter("udp.port == 5760", dialect).matches(f) for f in tcp) == 0
    with open_capture(CAPTURES / "px4_sitl.tlog") as r:
        tlog = [f for f in Dissector(dialect).run(r) if type(f) is not Anomaly]
    assert sum(compile_filter("frame.transport == tlog", dialect).matches(f) for f in tlog) == len(tlog)
    assert sum(compile_filter("ip.src == 127.0.0.1", dialect).matches(f) for f in tlog) == 0


def test_verdict_names_on_damaged(dialect: Dialect) -> None:
    with open_capture(CAPTURES / "damaged.pcap") as r:
        frames = [f for f in Dissector(dialect).run(r) if type(f) is not Anomaly]
    e = EXPECTED["damaged.pcap"]
    assert sum(compile_filter("mavlink.crc_status == bad", dialect).matches(f) for f in frames) == e["crc_bad"]
    assert sum(compile_filter("crc_status == unchecked", dialect).matches(f) for f in frames) == e["crc_unchecked"]
    assert sum(compile_filter("!mavlink.msgname", dialect).matches(f) for f in frames) == e["crc_unchecked"]
    assert sum(compile_filter("note.skipped-bytes", dialect).matches(f) for f in frames) >= 2


@pytest.mark.parametrize("text, message, pos, length", [
    ("COMMAND_LONG.comand == 20", 'unknown field "COMMAND_LONG.comand"', 0, 19),
    ("mavlink.sysid == 1 and HEARTBEET", 'unknown field "HEARTBEET"', 23, 9),
    ("mavlink.sysid ==", "unexpected end of filter", 16, 1),
    ("(HEARTBEAT", "expected ')'", 10, 1),
    ("HEARTBEAT)", "unexpected ')'", 9, 1),
    ('STATUSTEXT.text == "abc', "unterminated string", 19, 4),
    ("mavlink.crc_status == bda", '"bda" is not one of', 22, 3),
    ("command == MAV_CMD_NAV_RTL", "not a number, nor an enum name", 11, 15),
    ("HEARTBEAT == 0", "is a message", 0, 9),
    ("mavlink.sysid contains 1", '"contains" needs', 23, 1),
    ('STATUSTEXT.text matches "("', "bad regular expression", 24, 3),
    ("mavlink.sysid == 1 $", "unexpected character '$'", 19, 1),
    ("", "empty filter", 0, 1),
    ("ip.src == 300.1.1.1", "not an IP address", 10, 9),
    ("and", "expected a field name", 0, 3),
])
def test_errors_carry_the_position(dialect: Dialect, text: str, message: str, pos: int, length: int) -> None:
    with pytest.raises(FilterError) as info:
        compile_filter(text, dialect)
    err = info.value
    assert message in err.message
    assert (err.position, err.length) == (pos, length)
    lines = str(err).splitlines()
    assert lines[1] == "  " + text
    assert lines[2] == "  " + " " * pos + "^" + "~" * (length - 1)


def test_precedence_and_binds_tighter_than_or() -> None:
    node = parse("A or B and C")
    assert type(node).__name__ == "BoolOp" and node.op == "||"  # type: ignore[union-attr]


def test_payload_decoding_only_when_needed(dialect: Dialect) -> None:
    assert not compile_filter("mavlink.sysid == 1 && HEARTBEAT", dialect).needs_payload
    assert compile_filter("HEARTBEAT.type == 2", dialect).needs_payload


def test_read_with_display_filter(cli: Cli) -> None:
    status, out, err = cli("read", str(CAPTURES / "px4_sitl_udp.pcap"), "-Y", "mavlink_proto.msgid == 73")
    assert status == 0 and err == ""
    lines = out.splitlines()
    assert len(lines) == MSGIDS[73] and all("MISSION_ITEM_INT" in line for line in lines)
    status, out, _ = cli("read", str(CAPTURES / "px4_sitl_udp.pcap"), "-Y", "COMMAND_ACK", "-T", "jsonl")
    assert [json.loads(line)["msgname"] for line in out.splitlines()] == ["COMMAND_ACK"] * MSGIDS[77]


def test_read_filter_error_exit_2(cli: Cli) -> None:
    status, out, err = cli("read", str(CAPTURES / "px4_sitl_udp.pcap"), "-Y", "COMMAND_LONG.comand == 20")
    assert status == 2 and out == ""
    assert err.splitlines() == [
        'mavscope: filter error: unknown field "COMMAND_LONG.comand"; did you mean "COMMAND_LONG.command"?',
        "  COMMAND_LONG.comand == 20",
        "  ^~~~~~~~~~~~~~~~~~~",
    ]
