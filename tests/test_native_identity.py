"""The native engine and the pure-Python path print the same `read -T jsonl`, byte for byte.

Run through the real command line (`main`) with MAVSCOPE_PURE=1 and without, on every bundled capture
and every real capture beside the repository, with and without key material.
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from mavscope.cli import Env, main
from tests.conftest import CAPTURES, REAL_CAPTURES

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

BUNDLED = sorted(p.name for p in CAPTURES.iterdir() if p.suffix not in (".md", ".json"))
SIGNED_UDP_KEY = "hex:ac2193ecb3be4d7e444e2867d430a8b1618cd2ac1ed9710d580a79630f5420f0"
KEY_OPTIONS = {
    "no-keys": [],
    "key": ["--key", SIGNED_UDP_KEY],
    "leaked": ["--use-leaked-keys"],
}


def run(argv: list[str], pure: bool) -> tuple[int, bytes, str]:
    out = io.TextIOWrapper(io.BytesIO(), encoding="utf-8")
    err = io.StringIO()
    environ = {"MAVSCOPE_PURE": "1"} if pure else {}
    status = main(argv, Env(stdout=out, stderr=err, environ=environ))
    out.flush()
    return status, out.buffer.getvalue(), err.getvalue()  # type: ignore[attr-defined]


def assert_same(path: Path, extra: list[str]) -> None:
    argv = ["read", str(path), "-T", "jsonl", *extra]
    pure = run(argv, pure=True)
    native = run(argv, pure=False)
    assert native[0] == pure[0]
    assert native[2] == pure[2]
    assert native[1] == pure[1]


@pytest.mark.parametrize("keys", sorted(KEY_OPTIONS))
@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_capture(name: str, keys: str) -> None:
    assert_same(CAPTURES / name, KEY_OPTIONS[keys])


def real_captures() -> list[str]:
    if not REAL_CAPTURES.is_dir():
        return []
    return sorted(p.name for p in REAL_CAPTURES.iterdir() if p.suffix != ".md")


@pytest.mark.parametrize("name", real_captures() or ["(absent)"])
def test_real_capture(name: str, real_captures: Path) -> None:
    assert_same(real_captures / name, [])


def test_engine_is_named_and_pure_can_be_forced() -> None:
    from mavscope.native import engine

    assert engine({}) == "native"
    assert engine({"MAVSCOPE_PURE": "1"}) == "pure-python"
    assert engine({"MAVSCOPE_PURE": "0"}) == "native"
