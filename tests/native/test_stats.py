"""`mavscope stats` on the native engine prints what the pure-Python path prints.

Through the command line (MAVSCOPE_PURE=1 and without) on every bundled capture (without keys, with the
key of signed_udp.pcap, with --use-leaked-keys) and every real capture beside the repository, `--json`
and the text tables: stdout, stderr and exit status equal. The pure path is the reference; the native
pass must also have done the work (it does not give up on these captures, nor on one with every sender
there can be). Where it gives up (a table full: tests/native/test_stats_limits.py; a dialect the plan
cannot describe) the command prints the pure path's output.
"""

from __future__ import annotations

import math
import random
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
def test_the_native_pass_serves_every_bundled_capture(name: str) -> None:
    """Not a fallback: the native pass itself gives the pure path's statistics, findings and problems."""
    native = native_stats_of(CAPTURES / name, DIALECT)
    assert native is not None
    assert native == pure_stats(CAPTURES / name, DIALECT)
    assert native_stats_of(CAPTURES / name, DIALECT, window=64) == native  # records across read windows


@pytest.mark.parametrize("fmt", sorted(FORMATS))
@pytest.mark.parametrize("name", real_names() or ["(absent)"])
def test_real_capture(name: str, fmt: str, real_captures: Path, cli: Cli) -> None:
    same_stats(cli, real_captures / name, *FORMATS[fmt])


def test_real_captures_through_the_api(real_captures: Path) -> None:
    for name in real_names():
        native = native_stats_of(real_captures / name, DIALECT)
        assert native is not None, name
        assert native == pure_stats(real_captures / name, DIALECT), name


def test_many_senders_stay_on_the_native_pass(cli: Cli) -> None:
    """21,846 senders (every third of all there can be), every seventh of them heard twice, then a problem
    on stderr: the accumulator holds them (it holds 65,536; it once gave up past 16,384 senders and ran the
    pure path, 4 times slower on such a capture), and the command prints the pure path's output."""
    hb = DIALECT.messages[0]
    payload = struct.pack("<IBBBBB", 0, 2, 3, 0x81, 4, 3)
    entries = [(1_700_000_000_000_000 + k * 1000, nh.frame_v2(hb, 0, payload, k % 256, k >> 8, k & 0xFF))
               for k in [*range(0, 65_536, 3), *range(0, 65_536, 21)]]
    entries.append((1_700_000_200_000_000, b"\xfd\x01"))  # a problem on stderr (printed once)
    with capture_file(nh.tlog(entries)) as path:
        assert native_stats_of(path, DIALECT) is not None
        same_stats(cli, path, "--json")


def test_a_dialect_without_a_plan_runs_the_pure_path(tmp_path: Path, cli: Cli) -> None:
    """A message named like the label of an unknown id (UNKNOWN_<n>): the plan cannot describe the
    dialect, `stats` runs the pure path."""
    xml = tmp_path / "odd.xml"
    xml.write_text('<?xml version="1.0"?><mavlink><messages><message id="42424" name="UNKNOWN_7">'
                   '<description>x</description><field type="uint8_t" name="a">a</field></message>'
                   "</messages></mavlink>")
    from mavscope.native.plan import build_plan

    assert build_plan(load_dialect([xml])) is None
    assert build_plan(DIALECT) is not None
    same_stats(cli, CAPTURES / "px4_sitl_udp.pcap", "--dialect", str(xml), "--json")


def test_hypot_of_16_bit_integers_is_the_rounded_root() -> None:
    """gnss.c computes GLOBAL_POSITION_INT's speed as sqrt(vx * vx + vy * vy) where gnss.py calls
    math.hypot: equal for integers of 16 bits (every pair was compared once, docs/native.md; here a
    sample, the edges and both orders and signs)."""
    rng = random.Random(12)
    pairs = [(rng.randint(-32768, 32767), rng.randint(-32768, 32767)) for _ in range(200_000)]
    pairs += [(a, b) for a in (0, 1, -1, 32767, -32768, 181, 30000) for b in (0, 1, -1, 32767, -32768, 23170)]
    for x, y in pairs:
        exact = math.sqrt(float(x * x + y * y))
        assert math.hypot(x, y) == exact == math.hypot(-y, x), (x, y)

