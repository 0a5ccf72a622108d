"""float32 values as text: the shortest decimal that reads back as the same float32 (issue 35 item 15).

Expected texts are derived by hand (the interval of reals that round to the float32, written next to
each case) and, as an independent oracle, from numpy.float32's repr (Dragon4 in numpy's C code: the
shortest digits that round-trip, the nearest of them), whose digits mavscope's must equal; the layout is
Python's repr of a float (fixed notation for decimal exponents -4..15), which numpy.float32's repr uses
below 1e6 too. Neither is mavscope's own output.
"""

from __future__ import annotations

import math
import random
import struct
from decimal import Decimal

import pytest

from mavscope.mavlink.floats import f32_text, f32_value, float_text
from mavscope.mavlink.semantics import float_text as shown


def f32(x: float) -> float:
    """The float32 nearest x (round to nearest, ties to even), widened: what struct.unpack("<f") gives."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def from_bits(bits: int) -> float:
    return struct.unpack("<f", struct.pack("<I", bits))[0]


# (value, text): each derived by hand
HAND = [
    # 30.48 is 0x41F3D70A = 30.479999542236328125; a float32 step at 16..32 is 2**-19 (1.9e-6), so the
    # reals within 9.5e-7 of it read back as it: 30.48 is (4.6e-7 away), 30.5 and 30.47 are not.
    (f32(30.48), "30.48"),
    (f32(0.1), "0.1"),  # 0.100000001490116...; 0.1 is 1.5e-9 away, the half step 3.7e-9
    # the least subnormal, 2**-149 = 1.4012985e-45: reals within 2**-150 (7.0e-46) of it read back as it
    (from_bits(1), "1e-45"),
    # FLT_MAX = 340282346638528859811704183484516925440, half a step 2**103 = 1.01e31: 3.4028235e38 is
    # 3.4e30 away, 3.402823e38 is 4.7e31 away (and 3.402824e38 5.3e31)
    (from_bits(0x7F7FFFFF), "3.4028235e+38"),
    (-0.0, "-0.0"),
    (0.0, "0.0"),
    # 16777217 = 2**24 + 1 has no float32: it rounds to even, 2**24 = 16777216, which needs its 8 digits
    # (1.677722e7 is 4 away, the half step 1)
    (f32(16777217.0), "16777216.0"),
    (f32(100.0), "100.0"),
    (f32(1e-5), "1e-05"),  # Python's repr: an exponent below -4 in scientific notation, two digits
    (f32(0.0001), "0.0001"),
    # 12.2036295 needs 9 digits: the float32 is 12.203629493713379, the half step 2**-21 (4.8e-7); the
    # 8-digit neighbours 12.203629 and 12.20363 are 4.9e-7 and 5.1e-7 away: outside
    (12.203629493713379, "12.2036295"),
    # a power of two: the float32 below it is half a step nearer, so the interval is [v - step/4, v + step/2].
    # 2**90 = 1237940039285380274899124224; step 2**67 (1.48e20): 1.2379401e27 is 6.0e19 above (inside,
    # < 7.4e19), 1.2379400e27 is 3.9e19 below (outside: > 3.7e19). `%.8g` gives that one, so the usual
    # "shortest %.{p}g that round-trips" loop needs 9 digits here (1.23794004e+27).
    (2.0**90, "1.2379401e+27"),
    (2.0**-96, "1.2621775e-29"),
    (-(2.0**87), "-1.5474251e+26"),
]


@pytest.mark.parametrize(("value", "text"), HAND, ids=[t for _, t in HAND])
def test_hand_picked(value: float, text: str) -> None:
    assert f32_text(value) == text
    assert f32(float(text)) == value and math.copysign(1, f32(float(text))) == math.copysign(1, value)
    assert repr(f32_value(value)) == text  # the double whose own repr (and orjson's digits) is the text


def test_spelling_of_nan_and_infinities_is_unchanged() -> None:
    """NaN reads NaN (semantics.NAN_TEXT) and infinities inf/-inf, as before."""
    assert shown(math.nan, True) == shown(-math.nan, False) == "NaN"
    assert shown(math.inf, True) == "inf" and shown(-math.inf, True) == "-inf"
    assert shown(f32(30.48), True) == "30.48"
    assert float_text(f32(30.48), False) == "30.479999542236328"  # a double keeps repr


def _shortest_decimal(text: str) -> Decimal:
    return Decimal(text).normalize()


def test_digits_equal_numpy_float32_repr() -> None:
    """The digits equal numpy.float32's repr over random bit patterns, every power of two and its
    neighbours, subnormals, and the values people type (k / 100, k / 1000)."""
    np = pytest.importorskip("numpy", reason="numpy (the fleet extra) is the oracle")
    rng = random.Random(3505)
    bits = [rng.randrange(1, 0x7F800000) for _ in range(20_000)] + list(range(1, 2000))
    bits += [(e << 23) + d for e in range(1, 255) for d in (-1, 0, 1)]
    values = [from_bits(b & 0x7FFFFFFF) for b in bits]
    values += [f32(k / 100) for k in range(0, 20_000, 7)] + [f32(k / 1000) for k in range(0, 20_000, 11)]
    values += [-v for v in values[:2000]]
    bad = []
    for v in values:
        oracle = repr(np.float32(v)).removeprefix("np.float32(").removesuffix(")")
        mine = f32_text(v)
        if _shortest_decimal(mine) != _shortest_decimal(oracle) or f32(float(mine)) != v:
            bad.append((v, mine, oracle))
    assert not bad[:10]


def test_a_double_out_of_float32_range_is_left_alone() -> None:
    assert f32_value(1e300) == 1e300 and f32_value(1e-300) == 1e-300
