"""Shared by the analysis tests: a bundled capture's frames (dissected once) and its truth."""

from __future__ import annotations

import json
from functools import lru_cache

from mavscope.capture.detect import open_capture
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.pipeline.dissect import Anomaly, Dissector
from tests.conftest import CAPTURES

EXPECTED = json.loads((CAPTURES / "expected.json").read_text())


def truth(name: str) -> dict:
    return EXPECTED[name]["truth"]


@lru_cache(maxsize=None)
def _frames(name: str, dialect_id: int, dialect: Dialect) -> tuple[Frame, ...]:
    with open_capture(CAPTURES / name) as r:
        return tuple(f for f in Dissector(dialect).run(r) if type(f) is not Anomaly)


def frames(name: str, dialect: Dialect) -> list[Frame]:
    return list(_frames(name, id(dialect), dialect))
