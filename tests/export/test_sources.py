"""The batch-source seam: every registered source yields the declared schemas and the pure-Python
source's rows (the native source is held to this), and sources are looked up by name.

The reference is the `python` source (the pure pipeline, tested against pymavlink, tshark and the JSON
contract elsewhere). Tables are compared whole: the schema of every batch (metadata included) and every
row of every table (frames, each message table, findings, anomalies, captures without its export time
and source name), floats by their bit patterns (NaN payloads, -0.0). Over every bundled capture (without
and with the key that verifies its signed frames, and `--use-leaked-keys`), every real capture, damaged
bytes, and hypothesis-generated captures (tests/native/test_generated.py's strategy: every link layer,
container, frame kind the walker takes or hands back); also with windows of a few frames and batches of
a few rows, so that handed-back frames interleave with native ones inside a window and across windows.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from pathlib import Path

import pyarrow as pa
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mavscope.errors import UsageError
from mavscope.export import ExportOptions, record_batches, register_source
from mavscope.export.source import SOURCES, source_name
from mavscope.mavlink.dialect import Dialect
from mavscope.native import export as native_source
from mavscope.pipeline.options import PipelineOptions
from tests.conftest import CAPTURES, Cli
from tests.native import build as nh
from tests.native.build import KEY_SPEC
from tests.native.engines import capture_file
from tests.native.test_generated import DAMAGED_FILES, FEWER, SETTINGS, capture
from tests.support.dataset import arrow_table
from tests.support.sources import same_tables

PATHS = sorted(p for p in CAPTURES.iterdir() if p.suffix not in (".md", ".json"))
DEMO_KEY = "passphrase:mavscope-demo"  # the generator signs the bundled captures' GCS frames with it
KEYS = {"none": PipelineOptions(), "key": PipelineOptions(keys=(DEMO_KEY,)),
        "leaked": PipelineOptions(use_leaked_keys=True)}
needs_native = pytest.mark.skipif(native_source._native is None, reason="the native extension is not built")


@pytest.fixture
def small_windows(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Windows of 7 native frames: handed-back frames fall inside and between windows."""
    monkeypatch.setattr(native_source, "WINDOW_FRAMES", 7)
    yield


def test_the_native_source_is_registered() -> None:
    assert "native" in SOURCES
    assert source_name("auto", {}) == ("native" if native_source._native is not None else "python")
    assert source_name("auto", {"MAVSCOPE_PURE": "1"}) == "python"
    assert source_name("auto", {"MAVSCOPE_PURE": "0"}) == source_name("auto", {})
    assert source_name("python", {}) == "python"


@needs_native
@pytest.mark.parametrize("keys", sorted(KEYS))
@pytest.mark.parametrize("path", PATHS, ids=lambda p: p.name)
def test_every_source_gives_the_python_rows(path: Path, keys: str) -> None:
    same_tables(path, KEYS[keys])


@needs_native
@pytest.mark.parametrize("path", PATHS, ids=lambda p: p.name)
def test_small_windows_and_batches_give_the_same_rows(path: Path, small_windows: None) -> None:
    same_tables(path, rows=5)


@needs_native
def test_every_real_capture_gives_the_python_rows(real_captures: Path) -> None:
    paths = sorted(p for p in real_captures.iterdir() if p.suffix != ".md")
    assert paths
    for path in paths:
        same_tables(path)
    # the captures that sign, with the key PROVENANCE.md gives (their signed frames handed back, some valid)
    same_tables(real_captures / "ap_sitl_attack1_signed_knownkey.pcap", PipelineOptions(keys=("passphrase:key",)))
    same_tables(real_captures / "gomavlib_signed_testvectors_key4F_DERIVED.raw",
                PipelineOptions(keys=("hex:" + "4f" * 32,)))


@needs_native
def test_real_captures_in_small_windows(real_captures: Path, small_windows: None) -> None:
    for path in sorted(p for p in real_captures.iterdir() if p.suffix != ".md"):
        if os.path.getsize(path) < 300_000:
            same_tables(path, rows=1000)


def _damaged(data: bytes, seed: int) -> bytes:
    """`data` with every 97th byte from `seed` on flipped and, for odd seeds, cut at two thirds."""
    out = bytearray(data)
    for i in range(seed % 97, len(out), 97):
        out[i] ^= 0x5A
    return bytes(out[: len(out) * 2 // 3] if seed % 2 else out)


@needs_native
@pytest.mark.parametrize("seed", [1, 2, 40])
@pytest.mark.parametrize("name", ["px4_sitl_udp.pcap", "signed_udp.pcap", "px4_sitl.tlog", "px4_sitl_sll2.pcapng",
                                  "px4_sitl_tcp.pcap", "mavlink_v1_udp.pcap"])
def test_damaged_captures_give_the_python_rows(name: str, seed: int) -> None:
    with capture_file(_damaged((CAPTURES / name).read_bytes(), seed)) as path:
        same_tables(path)


@needs_native
@SETTINGS
@given(capture(), st.sampled_from(["none", "none", "key", "leaked"]), st.sampled_from([65_536, 3]))
def test_generated_captures_give_the_python_rows(data: bytes, keys: str, rows: int) -> None:
    pipeline = {"none": PipelineOptions(), "key": PipelineOptions(keys=(KEY_SPEC,)),
                "leaked": PipelineOptions(use_leaked_keys=True)}[keys]
    with capture_file(data) as path:
        same_tables(path, pipeline, rows)


@needs_native
@FEWER
@given(*DAMAGED_FILES)
def test_arbitrary_bytes_give_the_python_rows(tail: bytes, head: bytes) -> None:
    with capture_file(head + tail) as path:
        same_tables(path)


def test_sources_by_name(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[str] = []

    def wrapped(path: str, cid: str, options: ExportOptions, progress: object,
                warn: object) -> Iterator[pa.RecordBatch]:
        seen.append(path)
        return SOURCES["python"](path, cid, options, progress, warn)  # type: ignore[arg-type]

    monkeypatch.setitem(SOURCES, "wrapped", wrapped)
    assert "wrapped" in SOURCES
    list(record_batches(PATHS[0], ExportOptions(source="wrapped")))
    assert seen == [str(PATHS[0])]
    with pytest.raises(UsageError, match="no batch source .no-such-source.*python"):
        list(record_batches(PATHS[0], ExportOptions(source="no-such-source")))
    register_source("registered", wrapped)
    try:
        assert next(record_batches(PATHS[0], ExportOptions(source="registered", tables=frozenset({"frames"}))))
    finally:
        SOURCES.pop("registered")


def test_export_says_which_source_read_each_capture(cli: Cli, tmp_path: Path) -> None:
    """`export` runs the native source where it is built, the pure one with MAVSCOPE_PURE=1 (as `read`)."""
    path = CAPTURES / "px4_sitl_udp.pcap"
    for environ, want in (({}, "native" if native_source._native is not None else "python"),
                          ({"MAVSCOPE_PURE": "1"}, "python")):
        root = tmp_path / f"ds-{want}-{len(environ)}"
        status, _, err = cli("export", str(path), "--parquet", str(root), environ=environ)
        assert status == 0, err
        assert arrow_table(root, "captures").column("batch_source").to_pylist() == [want]


@needs_native
def test_more_endpoints_than_the_walker_remembers(dialect: Dialect) -> None:
    """70,000 senders' ports: the walker's endpoint map grows, then starts over between two chunks
    (columns.h MS_COLS_ENDPOINTS), and the endpoints' ids with it; the rows stay the pure source's."""
    att = dialect.by_name["ATTITUDE"]
    records = [nh.pcap([], nh.LINKTYPES["ethernet"])]  # the header; records joined once (70,000 of them)
    for i in range(70_000):
        f = nh.frame_v2(att, att.id, bytes(att.length), i & 255, 1 + i % 3, 1)
        ip = nh.ipv4(bytes([10, 0, i // 64000, 1]), b"\x0a\x00\x00\x02", 17, nh.udp(1024 + i % 64000, 14550, f))
        packet = nh.link("ethernet", ip, False)
        records.append(struct.pack("<IIII", 1_700_000_000 + i // 1000, i % 1000, len(packet), len(packet)) + packet)
    with capture_file(b"".join(records)) as path:
        same_tables(path)
