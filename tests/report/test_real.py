"""The report of every shared real capture (../shared/real-captures, PROVENANCE.md) agrees with the commands
it draws on: findings `audit --json`'s, figures `stats --json`'s, events and map those of `events` and
`track` (tests/report/test_cli.py's comparison), the document valid against its schema, and the page well
under 5 MB. Skipped where the real captures are not there."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import REAL_CAPTURES, Cli
from tests.report.test_cli import _agrees

REAL = sorted(p.name for p in REAL_CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw", ".bin")) \
    if REAL_CAPTURES.is_dir() else []
MAX_PAGE = 5 * 1024 * 1024


@pytest.mark.skipif(not REAL, reason="no real captures in ../shared/real-captures")
@pytest.mark.parametrize("name", REAL)
def test_real_capture_report(cli: Cli, tmp_path: Path, name: str) -> None:
    _agrees(cli, tmp_path, REAL_CAPTURES / name)
    assert (tmp_path / "r.html").stat().st_size < MAX_PAGE
