"""Bounds of the analyses under a hostile flood (issue 35, item 1; docs/security.md, "Bounds"): what the analyst
needs (a large bad-CRC burst, the vehicle's arming and the ARM command, an established mission upload) is
still shown, and what the bound gave up is said as a `capacity` finding that `audit` (and the analysis's own
command) reports. Every expected answer is worked out by hand from the flood the test builds (comments say
how); each test fails under the old policy (the first N listed, the oldest transfer closed, an unbounded list).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mavscope.analysis import expert
from tests.support import flows

ENGINES = ({"MAVSCOPE_PURE": "0"}, {"MAVSCOPE_PURE": "1"})


def bad_crc(frame: bytes, k: int) -> bytes:
    """`frame` with its CRC's low byte xored with `k` (1..255): a bad CRC, each `k` fitting another CRC_EXTRA,
    so no (sender, id, CRC_EXTRA) group reaches a dialect mismatch's 5 frames."""
    return frame[:-2] + bytes((frame[-2] ^ k, frame[-1]))


def findings(cli, *argv: object) -> dict[str, list[dict]]:  # type: ignore[no-untyped-def]
    status, out, err = cli(*argv, "--json")
    assert status in (0, 1), err
    got: dict[str, list[dict]] = {}
    for f in json.loads(out)["findings"]:
        got.setdefault(f["code"], []).append(f)
    return got


def test_a_flood_of_small_bad_crc_bursts_keeps_the_large_one(cli, tmp_path: Path,  # type: ignore[no-untyped-def]
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """A burst of 10 bad-CRC HEARTBEATs 0.1 s apart (records 1-10), then 6 bursts of 3 (0.1 s apart, 2 s between
    bursts: records 11-13, 14-16, ..., 26-28). With 3 bursts listed at most: the large one and the first two
    small ones fit; each later small one is the smallest and newest when it closes, so it goes itself (4
    give-ups, 12 frames), said at the 1st, 2nd and 4th: the bursts from records 17, 20 and 26. `stats` lists
    the large burst; `audit` (which lists no burst: not a security finding) reports the give-up."""
    monkeypatch.setattr(expert, "MAX_BURSTS", 3)
    gcs = flows.Sender(1, 1)
    entries = [(flows.T0 + i * 0.1, bad_crc(gcs.pack(flows.heartbeat()), 1 + i)) for i in range(10)]
    for b in range(6):
        entries += [(flows.T0 + 10 + b * 2 + j * 0.1, bad_crc(gcs.pack(flows.heartbeat()), 20 + 3 * b + j))
                    for j in range(3)]
    path = flows.write_tlog(tmp_path, entries)
    for environ in ENGINES:
        cli.environ = environ
        stats = findings(cli, "stats", path)
        assert [f["frames"] for f in stats["bad-crc-burst"]] == [list(range(1, 11)), [11, 12, 13], [14, 15, 16]]
        assert "dialect-mismatch" not in stats
        audit = findings(cli, "audit", path)
        (cap,) = audit["capacity"]
        assert cap["frames"] == [17, 20, 26]
        assert "4 given up (12 frames)" in cap["message"]
        assert stats["capacity"] == audit["capacity"]
