"""Expert findings on captures with known events."""

from __future__ import annotations

from mavscope.analysis.expert import DETECTORS, expert_findings, key_leaks
from mavscope.mavlink.dialect import Dialect
from tests.support.captures import frames, truth


def codes(findings) -> dict[str, list]:  # type: ignore[no-untyped-def]
    out: dict[str, list] = {}
    for f in findings:
        out.setdefault(f.code, []).append(f)
    return out


def test_commands_capture(dialect: Dialect) -> None:
    t = truth("commands_ack.pcap")
    found = codes(expert_findings(frames("commands_ack.pcap", dialect), dialect))
    (leak,) = found["key-leak"]
    assert leak.severity.value == "error" and leak.frames == (t["setup_signing_record"],)
    (replay,) = found["replayed-command"]
    assert replay.frames == (t["commands"][-1]["replay_of_record"], t["replay_record"])
    (new,) = found["new-commander"]
    assert "66/190" in new.message
    assert "seq-gap" not in found and "bad-crc-burst" not in found


def test_loss_capture(dialect: Dialect) -> None:
    found = codes(expert_findings(frames("stats_loss.pcap", dialect), dialect))
    (burst,) = found["bad-crc-burst"]
    assert len(burst.frames) == truth("stats_loss.pcap")["links"]["1/1"]["crc_bad"]
    (gap,) = found["seq-gap"]
    assert "40 frames lost" in gap.message
    assert len(found["seq-duplicate"]) == 1


def test_clean_captures_have_no_findings(dialect: Dialect) -> None:
    for name in ("px4_sitl_udp.pcap", "mission_resend.pcap", "clock_skew.pcap"):
        assert expert_findings(frames(name, dialect), dialect) == [], name


def test_detectors_are_an_open_list(dialect: Dialect) -> None:
    fs = frames("commands_ack.pcap", dialect)
    assert key_leaks in DETECTORS
    assert [f.code for f in expert_findings(fs, dialect, [key_leaks])] == ["key-leak"]
