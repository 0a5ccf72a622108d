"""The shipped pack over every real capture of ../shared/real-captures (PROVENANCE.md): on the ordinary
flights it raises nothing above `note` (docs/rules.md, "Real captures", says why for each exception); on the
one that holds an attack it names the injected frame, found here by pymavlink alone."""

from __future__ import annotations

from pathlib import Path

import pytest

from mavscope.mavlink.dialect import load_dialect
from mavscope.notes import Severity
from tests.conftest import REAL_CAPTURES
from tests.support.pymavlink_reader import read_pcap
from tests.support.ruleflows import pack_findings

DIALECT = load_dialect([])
ATTACK = "ap_sitl_attack1_signed_knownkey.pcap"
# capture -> the rules above note it may raise, each explained in docs/rules.md ("Real captures")
EXPECTED_ABOVE_NOTE: dict[str, set[str]] = {ATTACK: {"signing-timestamp-ahead"}}
SIGNING_EPOCH, AHEAD_S = 1_420_070_400, 3600.0  # MAVLink's signing epoch; the pack's signing-timestamp-ahead


def real(name: str) -> Path:
    path = REAL_CAPTURES / name
    if not path.exists():
        pytest.skip("../shared/real-captures is absent (a fresh clone)")
    return path


CAPTURES = sorted(p.name for p in REAL_CAPTURES.glob("*") if p.suffix in {".pcap", ".pcapng", ".tlog", ".raw", ".bin"})


@pytest.mark.parametrize("name", CAPTURES or ["(none)"])
def test_the_pack_on_every_real_capture(name: str) -> None:
    found = pack_findings(real(name))
    loud = {f.rule for f in found if f.severity > Severity.NOTE}
    assert loud == EXPECTED_ABOVE_NOTE.get(name, set()), [f.to_json() for f in found]


def test_the_attack_capture_names_the_frame_from_the_future() -> None:
    """The frames whose signature timestamp is more than an hour past their packet's time, read by pymavlink
    (the signature block: link id, then 6 bytes of timestamp, little-endian, 10 us units since 2015)."""
    path = real(ATTACK)
    ahead = [m.index for m in read_pcap(path) if (buf := m.msg.get_msgbuf())[0] == 0xFD and buf[2] & 1
             and int.from_bytes(buf[-12:-6], "little") / 1e5 + SIGNING_EPOCH - (m.time or 0) > AHEAD_S]
    assert ahead  # (PROVENANCE.md: an injected COMMAND_LONG a day ahead)
    (f,) = [f for f in pack_findings(path) if f.rule == "signing-timestamp-ahead"]
    assert list(f.frames) == ahead and f.severity is Severity.WARN
