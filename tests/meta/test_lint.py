"""The code passes the checks pyproject.toml sets: ruff (pyflakes, pycodestyle, import order) and mypy
(every function annotated, no unused `type: ignore`)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT


def _tool(name: str) -> str:
    beside = Path(sys.executable).with_name(name)
    exe = str(beside) if beside.exists() else shutil.which(name)
    if exe is None:
        pytest.skip(f"{name} is not installed (the test extras install it: make test)")
    return exe


def test_ruff_finds_nothing() -> None:
    proc = subprocess.run([_tool("ruff"), "check", "--no-cache", "mavscope", "scripts", "benchmarks", "tests"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_mypy_finds_nothing() -> None:
    proc = subprocess.run([_tool("mypy"), "--python-executable", sys.executable, "--cache-dir", "/dev/null"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
