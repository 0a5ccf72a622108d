"""One way into the command matcher (command_log.feed_command) for `commands`, `events`, `audit` and the
export, so that they cannot differ on a frame: the same frames taken, the same hostile fields skipped, and
in `audit` the fields the expert decoded passed on (each command frame decoded once).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as v2

from mavscope.analysis import command_log, expert
from mavscope.analysis.command_log import CommandMatcher, feed_command
from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import load_dialect
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import Cli
from tests.support import flows

ROOT = Path(__file__).resolve().parents[2] / "mavscope"


def test_the_matcher_is_fed_in_one_place() -> None:
    """`.add(` on a CommandMatcher (a name ending in `matcher`) is called in command_log.feed_command alone."""
    calls = [(p.relative_to(ROOT).as_posix(), line.strip()) for p in ROOT.rglob("*.py")
             for line in p.read_text().splitlines() if re.search(r"matcher\.add\(", line)]
    assert calls == [("analysis/command_log.py", "return matcher.add(f, fields)")]


def _frames(path: str) -> list:
    dialect = load_dialect()
    with open_capture(path) as reader:
        return [item for item in Dissector(dialect).run(reader) if type(item) is not Anomaly]


@pytest.mark.parametrize("bad", [float("inf"), float("nan"), "ARM", None])
def test_a_field_that_is_not_a_number_is_skipped(tmp_path: Path, bad: object) -> None:
    """A COMMAND_LONG whose decoded `command` is not a number (as a hostile dialect's decode could give): int()
    raises OverflowError for inf (which none of the three loops caught), ValueError for NaN and text,
    TypeError for None. The matcher skips it; the ACK after it is then an orphan."""
    gcs, vehicle = flows.Sender(255, 190), flows.Sender(1, 1)
    path = flows.write_tlog(tmp_path, [(flows.T0, gcs.pack(flows.command_long(400))),
                                       (flows.T0 + 1, vehicle.pack(v2.MAVLink_command_ack_message(400, 0)))])
    cmd, ack = _frames(path)
    matcher = CommandMatcher(load_dialect())
    fields = dict(command_log.decode_payload(cmd) or {}, command=bad)
    assert feed_command(matcher, cmd, fields) == (None, [])
    assert feed_command(matcher, ack) == (None, []) and len(matcher.orphans) == 1


def test_audit_decodes_each_command_frame_once(cli: Cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An ARM (record 1) and its ACK (record 2): the expert decodes the COMMAND_LONG and hands its fields to
    the matcher; the ACK, which no detector decodes, is decoded by feed_command: one decode per frame."""
    gcs, vehicle = flows.Sender(255, 190), flows.Sender(1, 1)
    path = flows.write_tlog(tmp_path, [(flows.T0, gcs.pack(flows.command_long(400))),
                                       (flows.T0 + 1, vehicle.pack(v2.MAVLink_command_ack_message(400, 0)))])
    decoded: list[int] = []
    for module in (expert, command_log):
        real = module.decode_payload

        def counting(f, real=real):  # type: ignore[no-untyped-def]
            decoded.append(f.record)
            return real(f)

        monkeypatch.setattr(module, "decode_payload", counting)
    status, _, _ = cli("audit", path, environ={"MAVSCOPE_PURE": "1"})
    assert sorted(r for r in decoded if r in (1, 2)) == [1, 2]
