"""The summary writer's numbers and strings equal Python's, byte for byte.

Each C formatter is checked against the Python expression fields/summary.py and output/text.py use
(`float_text(v, float32)`, `f"{v / 1e7:.7f}"`, `f"{t:11.6f}"`, `repr(char_text(b))`) over random values and
bit patterns, float32 values widened, subnormals, infinities, NaN, -0.0, every power of ten and its
neighbours, and values at and next to the rounding ties of each format (where the C fast paths hand over
to glibc's exact printf).
"""

from __future__ import annotations

import math
import random
import struct

import pytest

from mavscope.mavlink.dialect import char_text
from mavscope.mavlink.semantics import float_text

native = pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

RNG = random.Random(20261124)


def doubles_from_bits(n: int) -> list[float]:
    return [struct.unpack("<d", RNG.getrandbits(64).to_bytes(8, "little"))[0] for _ in range(n)]


def floats_widened(n: int) -> list[float]:
    return [struct.unpack("<f", RNG.getrandbits(32).to_bytes(4, "little"))[0] for _ in range(n)]


def edges() -> list[float]:
    out = [0.0, -0.0, math.inf, -math.inf, math.nan, -math.nan, 5e-324, -5e-324, 2.2250738585072014e-308,
           2.225073858507201e-308, 1.7976931348623157e308, 1.401298464324817e-45, 1.1754943508222875e-38,
           3.4028234663852886e38, 0.5, 1.5, 2.5, 1.0625, 1.0635, 9999.5, 99995.0, 0.00012345, 1.2345e-5,
           9.9995e-5, 9.99949999e-5, 1e-5, 1e15, 1e16, 123456789012.5]
    for e in range(-330, 310):
        try:
            p = float(f"1e{e}")
        except OverflowError:
            continue
        out += [p, math.nextafter(p, 0), math.nextafter(p, math.inf), -p]
    # decimal ties of four significant digits: d.ddd5 * 10**e (not exact in binary: either side of it)
    for _ in range(3000):
        text = f"{RNG.randint(1000, 9999)}5e{RNG.randint(-12, 16)}"
        v = float(text)
        out += [v, math.nextafter(v, 0), math.nextafter(v, math.inf)]
    # exact binary ties: k + 0.5 scaled by powers of two
    out += [(RNG.randint(1000, 9999) + 0.5) * 2.0 ** RNG.randint(-20, 20) for _ in range(3000)]
    return out


VALUES = edges() + doubles_from_bits(40_000) + floats_widened(40_000) + [RNG.uniform(-1e4, 1e4) for _ in range(20_000)]


def test_float_fields_equal_float_text() -> None:
    """A float32 field (VALUES rounded to float32 as the C cast rounds them) and a double field as
    fields/summary.py shows them (`float_text`: the shortest text that reads back as the same value)."""
    bad = []
    for v in VALUES:
        if not math.isfinite(v):
            continue  # (the writer spells NaN and infinities before these formatters: test_summary.py)
        try:
            f = struct.unpack("<f", struct.pack("<f", v))[0]
        except OverflowError:
            f = math.copysign(math.inf, v)
        if math.isfinite(f) and native.format_f32(v, 1) != float_text(f, True).encode():
            bad.append((v, native.format_f32(v, 1)))
        if native.format_double_repr(v) != float_text(v, False).encode():
            bad.append((v, native.format_double_repr(v)))
    assert not bad[:10]


def test_reltime_equals_the_time_column() -> None:
    spans = [v for v in VALUES if math.isfinite(v) and abs(v) < 1e15]
    spans += [RNG.uniform(0, 86400 * 3) for _ in range(20_000)]  # a capture's span, with microsecond ties:
    spans += [(RNG.randint(0, 10**12) + 0.5) / 1e6 for _ in range(20_000)]
    spans += [t - 1_700_000_000.0 for t in (1_700_000_000.0 + RNG.randint(0, 10**9) / 1e9 for _ in range(20_000))]
    bad = [(t, native.format_reltime(t)) for t in spans if native.format_reltime(t) != f"{t:11.6f}".encode()]
    assert not bad[:10]
    assert [native.format_reltime(t) for t in (math.inf, -math.inf, math.nan, 1e15, -2e15)] == [None] * 5


@pytest.mark.parametrize("bits,signed", [(8, True), (16, True), (32, True), (64, True), (8, False), (32, False),
                                         (64, False)])
def test_degrees_equal_python(bits: int, signed: bool) -> None:
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    values = [lo, hi, 0, 1, -1 if signed else 2, 5, -5 if signed else 7] + [RNG.randint(lo, hi) for _ in range(20_000)]
    values += [v for v in (2**40 - 1, 2**40, -(2**40), 2**53 + 1, -(2**53) - 1, 2**63 - 1) if lo <= v <= hi]
    bad = [v for v in values if native.format_degrees(v & (2**64 - 1), not signed) != f"{v / 1e7:.7f}".encode()]
    assert not bad[:10]


def test_repr_equals_python() -> None:
    alphabet = list(range(0, 128)) + [ord("'"), ord('"'), ord("\\"), 0, 0]
    samples = [bytes(RNG.choice(alphabet) for _ in range(RNG.randint(0, 40))) for _ in range(20_000)]
    samples += [b"", b"\0\0", b"a\0b\0", b"'", b'"', b"'\"", b"\\", b"\x7f\x1f\t\n\r", b"it's", b'say "hi"']
    for b in samples:
        assert native.repr_ascii(b) == repr(char_text(b)).encode(), b
    assert native.repr_ascii(b"caf\xc3\xa9") is None  # not ASCII: the record goes to Python
