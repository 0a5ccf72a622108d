"""The native JSON writer formats numbers and strings exactly as orjson does (mavscope's Python path).

Floats: the shortest round-trip digits (vendored Ryu) laid out by orjson's rules (fixed notation for
decimal exponents -5..15, `1.0`, `-0.0`, `1e+16`, `1e-7`, NaN and infinities as null), over random
doubles, random bit patterns, float32 values widened to double (how MAVLink float fields reach JSON)
and every power of ten with its neighbours. Strings: bytes decoded as UTF-8 with backslashreplace.
"""

from __future__ import annotations

import math
import struct

import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

native = pytest.importorskip("mavscope._native", reason="the native extension is not built")

EXAMPLES = settings(max_examples=3000, deadline=None, derandomize=True)


def same(x: float) -> None:
    assert native.format_double(x) == orjson.dumps(x), repr(x)


@EXAMPLES
@given(st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True))
def test_doubles(x: float) -> None:
    same(x)


@EXAMPLES
@given(st.integers(0, 2**64 - 1))
def test_double_bit_patterns(bits: int) -> None:
    same(struct.unpack("<d", struct.pack("<Q", bits))[0])


@EXAMPLES
@given(st.integers(0, 2**32 - 1))
def test_float32_values(bits: int) -> None:
    same(struct.unpack("<f", struct.pack("<I", bits))[0])


@EXAMPLES
@given(st.floats(width=32, allow_nan=True, allow_infinity=True, allow_subnormal=True))
def test_float32_strategy(x: float) -> None:
    same(x)


def test_powers_of_ten_and_neighbours() -> None:
    for e in range(-325, 310):
        try:
            x = float(f"1e{e}")
        except OverflowError:
            continue
        for v in (x, math.nextafter(x, 0.0), math.nextafter(x, math.inf), 9.999999999999999 * x / 10):
            same(v)
            same(-v)


def test_special_values() -> None:
    for v in (0.0, -0.0, 1.0, -1.0, math.nan, -math.nan, math.inf, -math.inf, 5e-324, 2.2250738585072014e-308,
              1.7976931348623157e308, 2.0**53, 2.0**53 + 2, 1e15, 1e16, 1e-5, 1e-6, 0.1, 1 / 3):
        same(v)


@settings(max_examples=2000, deadline=None, derandomize=True)
@given(st.binary(max_size=64))
def test_text(data: bytes) -> None:
    assert native.text_json(data) == orjson.dumps(data.decode("utf-8", "backslashreplace"))


@settings(max_examples=1000, deadline=None, derandomize=True)
@given(st.text(max_size=32))
def test_valid_utf8_text(text: str) -> None:
    data = text.encode("utf-8", "surrogatepass")
    assert native.text_json(data) == orjson.dumps(data.decode("utf-8", "backslashreplace"))
