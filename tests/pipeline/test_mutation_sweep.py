"""A short, deterministic mutation sweep over every bundled capture (the fuzz targets in tests/fuzz/ go
further with coverage guidance): the capture cut short at many bytes, bits flipped, and absurd lengths
written into record headers, block headers and MAVLink LEN bytes. Each mutant goes through the whole
pipeline and every rendering. Asserted: no exception; memory bounded by the input's size; on the raw
stream, every byte ends up in a frame, a truncated frame or a skipped-bytes note (none vanishes).
"""

from __future__ import annotations

import re
import struct
import tracemalloc
from pathlib import Path

import pytest

from mavscope.capture.detect import open_capture
from mavscope.fields.summary import summary_info
from mavscope.fields.tree import frame_items
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import CrcStatus
from mavscope.output.jsonout import jsonl_bytes
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import make_security_stage
from tests.conftest import CAPTURES

ALL = sorted(p for p in CAPTURES.iterdir() if p.suffix in (".pcap", ".pcapng", ".tlog", ".raw"))
POINTS = 24  # cuts and flips per capture
KEYS = PipelineOptions(keys=("passphrase:mavscope-demo",), ciphers=("2=aes-128-ctr:hex:" + "00" * 16,))
SKIPPED = re.compile(r"^(\d+) bytes that are not MAVLink skipped")


def mutants(data: bytes) -> list[tuple[str, bytes]]:
    n = len(data)
    out = []
    for k in range(POINTS):
        cut = (n * k) // POINTS + k % 7
        out.append((f"cut {cut}", data[:cut]))
        pos = (n * k + n // 2) // POINTS
        if pos < n:
            flipped = bytearray(data)
            flipped[pos] ^= 1 << (k % 8)
            out.append((f"flip {pos}.{k % 8}", bytes(flipped)))
    absurd = bytearray(data)
    if data[:4] == b"\xd4\xc3\xb2\xa1":  # pcap: the incl_len of the 2nd and 5th records
        pos, seen = 24, 0
        while pos + 16 <= n and seen < 5:
            incl = struct.unpack_from("<I", data, pos + 8)[0]
            seen += 1
            if seen in (2, 5):
                struct.pack_into("<I", absurd, pos + 8, 0xFFFFFFF0)
            pos += 16 + incl
    elif data[:4] == b"\x0a\x0d\x0d\x0a":  # pcapng: the length of the 3rd block
        pos = 0
        for _ in range(2):
            pos += struct.unpack_from("<I", data, pos + 4)[0]
        if pos + 8 <= n:
            struct.pack_into("<I", absurd, pos + 4, 0xFFFFFFF0)
    for m in list(re.finditer(rb"\xfd", data))[:8]:  # MAVLink LEN after a v2 STX
        if m.start() + 1 < n:
            absurd[m.start() + 1] = 0xFF
    out.append(("absurd lengths", bytes(absurd)))
    return out


def run_all(path: Path, dialect: Dialect) -> tuple[int, int, int]:
    """The whole pipeline and every rendering; (frame bytes, truncated-frame bytes, skipped bytes)."""
    framed = truncated = skipped = 0
    with open_capture(path) as reader:
        for i, item in enumerate(make_security_stage(KEYS).run(Dissector(dialect).run(reader))):
            notes = item.notes
            for n in notes:
                m = SKIPPED.match(n.message) if n.code == "skipped-bytes" else None
                skipped += int(m.group(1)) if m else 0
            if type(item) is Anomaly:
                continue
            if item.crc_status is CrcStatus.TRUNCATED:
                truncated += len(item.raw)
            else:
                framed += len(item.raw)
            jsonl_bytes(item)
            if not i % 7:
                summary_info(item, dialect)
                frame_items(item, dialect)
    return framed, truncated, skipped


@pytest.mark.parametrize("capture", ALL, ids=lambda p: p.name)
def test_mutants_never_raise_and_stay_bounded(capture: Path, dialect: Dialect, tmp_path: Path) -> None:
    data = capture.read_bytes()
    for what, mutant in mutants(data):
        path = tmp_path / ("m" + capture.suffix)
        path.write_bytes(mutant)
        tracemalloc.start()
        try:
            framed, truncated, skipped = run_all(path, dialect)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        assert peak < 64 * len(mutant) + (16 << 20), (what, peak)
        if capture.suffix == ".raw":  # a raw stream is all MAVLink: every byte is accounted for
            assert framed + truncated + skipped == len(mutant), what
