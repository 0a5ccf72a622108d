"""The code passes the lint rules pyproject.toml sets (ruff: pyflakes, pycodestyle, import order)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT


def test_ruff_finds_nothing() -> None:
    ruff = Path(sys.executable).with_name("ruff")
    exe = str(ruff) if ruff.exists() else shutil.which("ruff")
    if exe is None:
        pytest.skip("ruff is not installed (the test extras install it: make test)")
    proc = subprocess.run([exe, "check", "--no-cache", "mavscope", "scripts", "benchmarks", "tests"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
