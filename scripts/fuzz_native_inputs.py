"""What scripts/fuzz-native.sh gives the native fuzzer: the default dialect's tables, and the seed corpus.

    python scripts/fuzz_native_inputs.py OUT_DIR CORPUS_DIR

writes OUT_DIR/table.bin (message layouts), summary.bin (the summary writer's table) and notes.bin (the
notes the walker writes itself and MAVLink's UDP ports, as the glue hands them over:
mavscope.native.walk.note_templates and MAVLINK_PORTS; notes_blob says the layout), and seeds CORPUS_DIR:
every bundled capture under the selector of its own format (0 pcap, 1 pcapng, 2 tlog, 3 raw), with and
without native signed frames (bit 2), with every CRC taken (bit 3), judged with keys (a preset sender,
bits 4-6, bit 2 clear), and as hostile files (bit 7: a control byte, then a small read window, shrinking,
a failed read); and 600 frames of the bench capture
(benchmarks/bench_capture.py, two senders signing). fuzz/fuzz_native.c documents the selector.
tests/meta/test_fuzz_inputs.py runs both halves, so a moved builder fails the suite, not the fuzzer.
"""

from __future__ import annotations

import hashlib
import importlib.util
import struct
import sys
import tempfile
from pathlib import Path

from mavscope.capture.detect import detect_kind
from mavscope.mavlink.dialect import load_dialect
from mavscope.native.summary import build_summary_table
from mavscope.native.table_blob import build_table
from mavscope.native.walk import note_templates
from mavscope.pipeline.dissect import MAVLINK_PORTS

ROOT = Path(__file__).resolve().parents[1]
SELECTOR = {"pcap": 0, "pcapng": 1, "tlog": 2, "raw": 3}
EXTRAS = (0, 4, 8, 12, 0x10, 0x18, 0x70)
# a 64-byte read window; shrinking after 2 reads to 2/7; a failed read; a 512-byte window and the set of
# MAVLink sources nearly full
HOSTILE_CONTROLS = (0x00, 0x10, 0x38, 0x43)


def write_tables(out: Path) -> None:
    """The default dialect's message table, summary table and note templates, as the fuzzer loads them."""
    dialect = load_dialect()
    out.mkdir(parents=True, exist_ok=True)
    (out / "table.bin").write_bytes(build_table(dialect))
    (out / "summary.bin").write_bytes(build_summary_table(dialect))
    (out / "notes.bin").write_bytes(notes_blob())


def notes_blob() -> bytes:
    """The walker's note templates and MAVLink's ports as the glue gives them (native/walk.py): per template
    (walk.h MS_TPL_*, in order) u8 piece count, then per piece u16 length and the bytes; then u16 port count
    and each port as u16 (all little-endian)."""
    blob = bytearray()
    for template in note_templates():
        blob += struct.pack("<B", len(template))
        for piece in template:
            blob += struct.pack("<H", len(piece)) + piece
    ports = sorted(MAVLINK_PORTS)
    blob += struct.pack(f"<H{len(ports)}H", len(ports), *ports)
    return bytes(blob)


def _bench_capture(path: Path, frames: int) -> None:
    spec = importlib.util.spec_from_file_location("bench_capture", ROOT / "benchmarks" / "bench_capture.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.generate(path, frames)


def write_seeds(corpus: Path) -> int:
    """Seed `corpus` (named by content, so re-running adds nothing twice): the number of seeds written."""
    corpus.mkdir(parents=True, exist_ok=True)
    seeds: set[bytes] = set()
    with tempfile.TemporaryDirectory() as tmp:
        bench = Path(tmp) / "bench.pcap"
        _bench_capture(bench, 600)
        paths = [p for p in sorted((ROOT / "captures").iterdir()) if p.suffix not in (".md", ".json")]
        for path in paths + [bench]:
            data = path.read_bytes()
            base = SELECTOR[detect_kind(path)]
            for extra in EXTRAS:
                for piece in (data[:4096], data[:65536]):
                    seeds.add(bytes([base | extra]) + piece)
            for control in HOSTILE_CONTROLS:
                seeds.add(bytes([base | 0x80, control]) + data[:16384])
    for blob in seeds:
        (corpus / hashlib.sha1(blob).hexdigest()).write_bytes(blob)
    return len(seeds)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: fuzz_native_inputs.py OUT_DIR CORPUS_DIR", file=sys.stderr)
        return 2
    write_tables(Path(argv[0]))
    write_seeds(Path(argv[1]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
