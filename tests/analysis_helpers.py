"""Shared by the analysis tests: run the real entry point, load a capture's frames and its truth."""

from __future__ import annotations

import io
import json
from functools import lru_cache

from mavscope.capture.detect import open_capture
from mavscope.cli import Env, main
from mavscope.dissect import Anomaly, Dissector
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from tests.conftest import CAPTURES

EXPECTED = json.loads((CAPTURES / "expected.json").read_text())


def truth(name: str) -> dict:
    return EXPECTED[name]["truth"]


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    status = main(list(argv), Env(stdout=out, stderr=err))
    return status, out.getvalue(), err.getvalue()


def run_json(*argv: str) -> dict:
    status, out, err = run(*argv, "--json")
    assert status == 0, err
    return json.loads(out)


@lru_cache(maxsize=None)
def _frames(name: str, dialect_id: int, dialect: Dialect) -> tuple[Frame, ...]:
    with open_capture(CAPTURES / name) as r:
        return tuple(f for f in Dissector(dialect).run(r) if type(f) is not Anomaly)


def frames(name: str, dialect: Dialect) -> list[Frame]:
    return list(_frames(name, id(dialect), dialect))
