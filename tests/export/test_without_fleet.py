"""Without the fleet extra: `read` and `batch` work, `export` and `sql` say in one line what to install.

A package named pyarrow whose import fails stands in for a missing one (put first on the path of a
child process)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.conftest import CAPTURES, ROOT

CAPTURE = str(CAPTURES / "mavlink_v1_udp.pcap")


def _mavscope(tmp_path: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    fake = tmp_path / "fake"
    (fake / "pyarrow").mkdir(parents=True, exist_ok=True)
    (fake / "pyarrow" / "__init__.py").write_text("raise ImportError('No module named pyarrow', name='pyarrow')\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(fake), str(ROOT)])}
    return subprocess.run([sys.executable, "-m", "mavscope", *argv], capture_output=True, text=True, env=env,
                          timeout=120, check=False)


def test_core_commands_without_pyarrow(tmp_path: Path) -> None:
    p = _mavscope(tmp_path, "read", CAPTURE, "-c", "1")
    assert p.returncode == 0 and "HEARTBEAT" in p.stdout, p.stderr
    p = _mavscope(tmp_path, "batch", CAPTURE, "--", "stats")
    assert p.returncode == 0 and "1 ok" in p.stdout, p.stderr
    for argv in (("export", CAPTURE, "--parquet", str(tmp_path / "ds")), ("sql", "SELECT 1", CAPTURE)):
        p = _mavscope(tmp_path, *argv)
        assert p.returncode == 2, p.stderr
        assert p.stderr == "mavscope: this command needs pyarrow: pip install 'mavscope[fleet]'\n"
    assert not (tmp_path / "ds").exists()
