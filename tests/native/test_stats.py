"""`mavscope stats` on the native engine prints what the pure-Python path prints.

One implementation of every statistic and finding (mavscope.analysis, over FrameBatches) fed by two
frame sources: the native walker's windows (notes as codes) and the Python pipeline's frames. Through the
command line (MAVSCOPE_PURE=1 and without) on every bundled capture (without keys, with the key of
signed_udp.pcap, with --use-leaked-keys) and every real capture beside the repository, `--json` and the
text tables: stdout, stderr and exit status equal; and through the API against the per-frame reference
(StatsBuilder.add and Expert.add frame by frame, tests/native/stats_engines.py), with windows of a few
rows so that every batch boundary is crossed.
"""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from mavscope.mavlink.dialect import load_dialect
from tests.conftest import CAPTURES, Cli
from tests.native import build as nh
from tests.native.engines import PURE, capture_file
from tests.native.stats_engines import native_stats_of, pure_stats
from tests.native.test_identity import BUNDLED, KEY_OPTIONS, real_names

pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

DIALECT = load_dialect()
FORMATS = {"json": ("--json",), "text": ()}


def same_stats(cli: Cli, path: str | Path, *extra: str) -> None:
    pure = cli("stats", str(path), *extra, environ=PURE)
    native = cli("stats", str(path), *extra, environ={})
    assert native.err == pure.err
    assert native.out == pure.out
    assert native.status == pure.status


@pytest.mark.parametrize("fmt", sorted(FORMATS))
@pytest.mark.parametrize("keys", sorted(KEY_OPTIONS))
@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_capture(name: str, keys: str, fmt: str, cli: Cli) -> None:
    same_stats(cli, CAPTURES / name, *KEY_OPTIONS[keys], *FORMATS[fmt])


@pytest.mark.parametrize("name", BUNDLED)
def test_the_batches_give_the_per_frame_answers_on_every_bundled_capture(name: str) -> None:
    """Not a fallback: the native pass itself gives the pure path's statistics, findings and problems."""
    native = native_stats_of(CAPTURES / name, DIALECT)
    assert native == pure_stats(CAPTURES / name, DIALECT)
    assert native_stats_of(CAPTURES / name, DIALECT, limit=7) == native  # windows of 7 rows


@pytest.mark.parametrize("fmt", sorted(FORMATS))
@pytest.mark.parametrize("name", real_names() or ["(absent)"])
def test_real_capture(name: str, fmt: str, real_captures: Path, cli: Cli) -> None:
    same_stats(cli, real_captures / name, *FORMATS[fmt])


def test_real_captures_through_the_api(real_captures: Path) -> None:
    for name in real_names():
        native = native_stats_of(real_captures / name, DIALECT)
        assert native == pure_stats(real_captures / name, DIALECT), name


def test_many_senders(cli: Cli) -> None:
    """21,846 senders (every third of all there can be), every seventh of them heard twice, then a problem
    on stderr: both engines print the same, and the batches give the per-frame answers."""
    hb = DIALECT.messages[0]
    payload = struct.pack("<IBBBBB", 0, 2, 3, 0x81, 4, 3)
    entries = [(1_700_000_000_000_000 + k * 1000, nh.frame_v2(hb, 0, payload, k % 256, k >> 8, k & 0xFF))
               for k in [*range(0, 65_536, 3), *range(0, 65_536, 21)]]
    entries.append((1_700_000_200_000_000, b"\xfd\x01"))  # a problem on stderr (printed once)
    with capture_file(nh.tlog(entries)) as path:
        assert native_stats_of(path, DIALECT) == pure_stats(path, DIALECT)
        same_stats(cli, path, "--json")


def test_a_dialect_naming_a_message_like_an_unknown_id(tmp_path: Path, cli: Cli) -> None:
    """A message named like the label of an unknown id (UNKNOWN_<n>): both engines print the same."""
    xml = tmp_path / "odd.xml"
    xml.write_text('<?xml version="1.0"?><mavlink><messages><message id="42424" name="UNKNOWN_7">'
                   '<description>x</description><field type="uint8_t" name="a">a</field></message>'
                   "</messages></mavlink>")
    same_stats(cli, CAPTURES / "px4_sitl_udp.pcap", "--dialect", str(xml), "--json")
