"""Command/ACK pairing on a capture whose commands, results, retries and latencies are known."""

from __future__ import annotations

import pytest

from mavscope.mavlink.dialect import Dialect
from tests.conftest import CAPTURES, Cli
from tests.support.captures import truth

CMDS = str(CAPTURES / "commands_ack.pcap")
SENDERS = {"gcs": [255, 190], "rogue": [66, 190]}


def test_commands_match_the_truth(cli: Cli, dialect: Dialect) -> None:
    doc = cli.json("commands", CMDS)
    got, want = doc["commands"], truth("commands_ack.pcap")["commands"]
    assert len(got) == len(want)
    results = dialect.enums["MAV_RESULT"]
    for g, w in zip(got, want):
        assert g["command_id"] == w["command"] and g["message"] == w["kind"]
        assert g["from"] == SENDERS[w["from"]] and g["to"] == [1, 1]
        assert g["result"] == (results.name_of(w["result"]) if w["result"] is not None else None)
        assert g["retries"] == w["retries"]
        if w["latency_ms"] is None:
            assert g["latency_ms"] is None and not g["answered"]
        else:
            assert g["latency_ms"] == pytest.approx(w["latency_ms"], abs=0.002)
    assert doc["unanswered"] == 2 and doc["unmatched_acks"] == []
    assert {g["result"] for g in got} >= {"MAV_RESULT_DENIED", "MAV_RESULT_FAILED", "MAV_RESULT_ACCEPTED"}


def test_px4_session_rtl(cli: Cli) -> None:
    doc = cli.json("commands", str(CAPTURES / "px4_sitl_udp.pcap"))
    rtl = [c for c in doc["commands"] if c["command"] == "MAV_CMD_NAV_RETURN_TO_LAUNCH"]
    assert len(rtl) == 1 and rtl[0]["result"] == "MAV_RESULT_ACCEPTED" and 0 < rtl[0]["latency_ms"] < 20
    repo = [c for c in doc["commands"] if c["command"] == "MAV_CMD_DO_REPOSITION"]
    assert repo[0]["message"] == "COMMAND_INT" and repo[0]["params"]["x"] == pytest.approx(47.3985, abs=1e-3)


def test_filter_and_text(cli: Cli) -> None:
    doc = cli.json("commands", CMDS, "-Y", "mavlink.sysid != 66")
    assert all(c["from"] != [66, 190] for c in doc["commands"])
    status, out, _ = cli("commands", CMDS)
    assert status == 0 and "DENIED" in out and "UNANSWERED" in out and "8 commands, 2 unanswered" in out


def test_no_command_matching_says_so_instead_of_an_empty_table(cli: Cli) -> None:
    status, out, _ = cli("commands", CMDS, "-Y", "COMMAND_ACK")  # the ACKs still answer their commands
    assert status == 0 and out.startswith("No command in ") and "matches the display filter" in out
    assert "0 commands, 0 unanswered, 0 ACKs" in out and "┏" not in out


def test_a_filter_selects_rows_but_every_frame_is_analysed(cli: Cli) -> None:
    """Issue: `commands -Y '<the command>'` showed it UNANSWERED (its ACK had been filtered away)."""
    t = truth("commands_ack.pcap")
    doc = cli.json("commands", CMDS, "-Y", "COMMAND_LONG.command == MAV_CMD_COMPONENT_ARM_DISARM")
    answered = [c for c in doc["commands"] if c["answered"]]
    first = t["commands"][0]  # the generator's first command: an arm (400), accepted (0), 12.345 ms
    assert answered and answered[0]["command_id"] == first["command"] == 400
    assert answered[0]["result_id"] == first["result"] and answered[0]["latency_ms"] == first["latency_ms"]
