"""Shared fixtures: the default dialect (loaded once), paths to the bundled and real captures, and `cli`,
the one way the tests run the real command line (`mavscope.cli.main` with an `Env` of string streams).

Tests are grouped by layer (`capture/`, `transport/`, `mavlink/`, `pipeline/`, `security/`, `filter/`,
`analysis/`, `browse/`, `cli/`, `live/`, `tui/`), plus `crosscheck/` (pymavlink, tshark and the real
captures) and `meta/` (lint, types, layering). Helpers shared by several groups live in `support/`.
"""

from __future__ import annotations

import io
import json
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import NamedTuple

import pytest

from mavscope.cli import Env, main
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.dialect_cache import CACHE_ENV, NO_CACHE_ENV

ROOT = Path(__file__).resolve().parents[1]
CAPTURES = ROOT / "captures"
REAL_CAPTURES = ROOT.parent / "shared" / "real-captures"


class CliResult(NamedTuple):
    status: int
    out: str
    err: str


class Cli:
    """Runs `mavscope ARGV...` in-process with captured stdout and stderr (and an environment of its own)."""

    def __init__(self, environ: Mapping[str, str] | None = None) -> None:
        self.environ = dict(environ or {})

    def __call__(self, *argv: str, environ: Mapping[str, str] | None = None) -> CliResult:
        out, err = io.StringIO(), io.StringIO()
        env = Env(stdout=out, stderr=err, environ=dict(self.environ if environ is None else environ))
        status = main([str(a) for a in argv], env)
        return CliResult(int(status), out.getvalue(), err.getvalue())

    def json(self, *argv: str, environ: Mapping[str, str] | None = None) -> dict:
        """`mavscope ARGV... --json`, which must succeed (exit 0), parsed."""
        status, out, err = self(*argv, "--json", environ=environ)
        assert status == 0, err
        return json.loads(out)

    def jsonl(self, *argv: str, environ: Mapping[str, str] | None = None) -> list[dict]:
        """`mavscope read ARGV... -T jsonl`, which must succeed, one object per frame."""
        status, out, err = self("read", *argv, "-T", "jsonl", environ=environ)
        assert status == 0, err
        return [json.loads(line) for line in out.splitlines()]


@pytest.fixture(scope="session", autouse=True)
def dialect_cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The dialect cache of the whole run (and of the mavscope processes it starts): a temporary directory,
    never the user's ~/.cache (mavscope.mavlink.dialect_cache)."""
    path = tmp_path_factory.mktemp("dialect-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(CACHE_ENV, str(path))
        patch.delenv(NO_CACHE_ENV, raising=False)
        yield path


@pytest.fixture
def cli() -> Cli:
    return Cli()


@pytest.fixture(scope="session")
def dialect() -> Dialect:
    return load_dialect()


@pytest.fixture(scope="session")
def real_captures() -> Path:
    if not REAL_CAPTURES.is_dir():
        pytest.skip(f"{REAL_CAPTURES} is absent (it exists beside the repo in CI only)")
    return REAL_CAPTURES
