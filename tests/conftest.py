"""Shared fixtures: the default dialect (loaded once), paths to the bundled and real captures, and `cli`,
the one way the tests run the real command line (`mavscope.cli.main` with an `Env` of string streams).

Tests are grouped by layer (`capture/`, `transport/`, `mavlink/`, `pipeline/`, `security/`, `filter/`,
`analysis/`, `browse/`, `cli/`, `live/`, `tui/`), plus `crosscheck/` (pymavlink, tshark and the real
captures) and `meta/` (lint, types, layering). Helpers shared by several groups live in `support/`.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import pytest

from mavscope.cli import Env, main
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.dialect_cache import CACHE_ENV, NO_CACHE_ENV
from tests.support import tiers

# The hypothesis profiles (`fast` by default, `full` for `make test-slow`), loaded before any test module makes
# its settings; the tiers themselves are in tests/support/tiers.py (docs/testing.md, "Tiers").
tiers.register_profiles()

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


_SAVED_ENV: dict[str, str | None] = {}


@pytest.hookimpl(tryfirst=True)  # before `-m` selects by the markers
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The `slow` marker and the fast tier's property-test examples, from tests/support/tiers.py."""
    tiers.mark(items)


def pytest_configure(config: pytest.Config) -> None:
    """The dialect cache of the whole run (and of the mavscope processes it starts) in a temporary directory,
    never the user's ~/.cache (mavscope.mavlink.dialect_cache); set before collection, since some test
    modules load the dialect when imported. Each xdist worker configures its own."""
    _SAVED_ENV.update({name: os.environ.get(name) for name in (CACHE_ENV, NO_CACHE_ENV)})
    os.environ[CACHE_ENV] = tempfile.mkdtemp(prefix="mavscope-dialect-cache-")
    os.environ.pop(NO_CACHE_ENV, None)


def pytest_unconfigure(config: pytest.Config) -> None:
    if CACHE_ENV in _SAVED_ENV:
        shutil.rmtree(os.environ[CACHE_ENV], ignore_errors=True)
    for name, value in _SAVED_ENV.items():
        if value is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = value


@pytest.fixture
def cli() -> Cli:
    return Cli()


@pytest.fixture(scope="session")
def tshark_exe() -> str:
    """Path of tshark with Lua support, or skip every test that needs it (tests/support/tshark.py)."""
    from tests.support import tshark

    try:
        return tshark.find_tshark()
    except tshark.TsharkUnavailable as exc:
        pytest.skip(f"tshark cross-check skipped: {exc}")


@pytest.fixture(scope="session")
def lua_dissector(tshark_exe: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """pymavlink's Wireshark Lua dissector for the ``all`` dialect, generated once per session."""
    from tests.support import tshark

    try:
        lua = tshark.generate_lua_dissector(tmp_path_factory.mktemp("wlua"), "all")
        tshark.check_lua_loads(tshark_exe, lua)
    except tshark.TsharkUnavailable as exc:
        pytest.skip(f"tshark cross-check skipped: {exc}")
    return lua


@pytest.fixture(scope="session")
def dialect() -> Dialect:
    return load_dialect()


@pytest.fixture(scope="session")
def real_captures() -> Path:
    if not REAL_CAPTURES.is_dir():
        pytest.skip(f"{REAL_CAPTURES} is absent (it exists beside the repo in CI only)")
    return REAL_CAPTURES
