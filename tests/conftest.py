"""Shared fixtures: the default dialect (loaded once), paths to the bundled and real captures."""

from __future__ import annotations

from pathlib import Path

import pytest

from mavscope.mavlink.dialect import Dialect, load_dialect

ROOT = Path(__file__).resolve().parents[1]
CAPTURES = ROOT / "captures"
REAL_CAPTURES = ROOT.parent / "shared" / "real-captures"


@pytest.fixture(scope="session")
def dialect() -> Dialect:
    return load_dialect()


@pytest.fixture(scope="session")
def real_captures() -> Path:
    if not REAL_CAPTURES.is_dir():
        pytest.skip(f"{REAL_CAPTURES} is absent (it exists beside the repo in CI only)")
    return REAL_CAPTURES
