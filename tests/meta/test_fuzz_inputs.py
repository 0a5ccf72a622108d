"""The native fuzzer's inputs are made by the project's own code (scripts/fuzz_native_inputs.py, run by
scripts/fuzz-native.sh): the suite runs both halves, so a builder moved or renamed fails here and not
only when someone next fuzzes (stop 20: the script still imported the message table from its old home)."""

from __future__ import annotations

from pathlib import Path

from scripts import fuzz_native_inputs as inputs
from tests.conftest import CAPTURES


def test_tables_are_written(tmp_path: Path) -> None:
    inputs.write_tables(tmp_path)
    for name in ("table.bin", "summary.bin"):
        assert (tmp_path / name).stat().st_size > 1000, name
    assert (tmp_path / "notes.bin").stat().st_size > 0
    assert not (tmp_path / "plan.bin").exists()  # the stats accumulator and its plan are gone from C


def test_seeds_cover_every_bundled_capture(tmp_path: Path) -> None:
    n = inputs.write_seeds(tmp_path)
    blobs = [p.read_bytes() for p in tmp_path.iterdir()]
    assert n == len(blobs)
    captures = [p for p in CAPTURES.iterdir() if p.suffix not in (".md", ".json")]
    for path in captures:  # each under its own format's selector, whole (up to 4 KiB) after it
        head = path.read_bytes()[:4096]
        sel = inputs.SELECTOR[{".pcap": "pcap", ".pcapng": "pcapng", ".tlog": "tlog", ".raw": "raw"}[path.suffix]]
        assert bytes([sel]) + head in blobs, path.name
    assert sum(b[0] & 0x80 != 0 for b in blobs) >= len(inputs.HOSTILE_CONTROLS) * len(captures)
    assert inputs.write_seeds(tmp_path) == n and len(list(tmp_path.iterdir())) == n  # re-running adds nothing


def test_the_script_uses_them() -> None:
    script = (Path(inputs.__file__).parent / "fuzz-native.sh").read_text()
    assert "scripts/fuzz_native_inputs.py" in script
    assert "<<'PYEOF'" not in script  # no second, untested copy of the builders' imports
