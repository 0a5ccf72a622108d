"""MAVLink `float` (IEEE-754 binary32) values as text: the shortest decimal that reads back as the same float32.

A float32 widened to a Python float has up to 17 significant digits of which at most 9 matter:
PARAM_VALUE 30.48 arrives as 30.479999542236328. Every place that shows a float32 as text (the detail
tree, summary lines, commands, missions, parameters, events, tables, CSV, JSON) writes the shortest
decimal that a reader rounding to the nearest float32 (ties to even: C's strtof, numpy.float32(text))
turns back into the same bits, and of the shortest ones the nearest to the value: Ryu's `f2s`, which
the native engine runs (src/mavscope_native/vendor/ryu/ryu_f2d.h), and numpy.float32's repr. The digits
are laid out as Python's repr lays out a float (`30.48`, `100.0`, `-0.0`, `0.0001`, `1e-05`,
`3.4028235e+38`): numpy.float32's repr exactly. `double` values keep Python's repr (the same rule for
float64). How NaN and infinities read is each output's own (semantics.NAN_TEXT, `null` in JSON).

The search is exact: the float32 `a` owns the interval of reals that round to it, whose ends are doubles
(a 24-bit significand and half a step either side fit in 53 bits; below a power of two the step is
half as wide). A p-digit candidate (Python's correctly rounded `%.{p-1}e`) is compared with the ends
through its nearest double, which is on the same side of a double end as the decimal itself unless it
is that end; only then is the decimal compared exactly. A p-digit decimal exists in the interval iff the
nearest one does, or, where the interval is wider above (a power of two), the next one up: so "a
p-digit decimal reads back" is monotone in p and the shortest p is found by a few tries.
"""

from __future__ import annotations

import math
import struct
from decimal import Decimal

from mavscope.mavlink.dialect import MessageDef

_F32 = struct.Struct("<f")
_U32 = struct.Struct("<I")
_pack, _unpack, _bits = _F32.pack, _F32.unpack, _U32.unpack
_ldexp, _isfinite = math.ldexp, math.isfinite
_CACHE: dict[float, float] = {}  # value -> its shortest double: telemetry repeats values (a memo, cleared when full)
_CACHE_MAX = 8192


def _exact(text: str, lo: float, hi: float, inclusive: bool) -> bool:
    """Whether the decimal `text`, whose nearest double is an end of [lo, hi], lies in it."""
    exact, low, high = Decimal(text), Decimal(lo), Decimal(hi)
    return low < exact < high or (inclusive and (exact == low or exact == high))


def _candidate(a: float, p: int, lo: float, hi: float, inclusive: bool, wide_above: bool) -> str | None:
    """The p-digit decimal nearest `a` inside [lo, hi] (None when there is none): the correctly rounded
    one, or where the interval is wider above and that one fell below, the next one up."""
    text = "%.*e" % (p - 1, a)
    d = float(text)
    if lo < d < hi:
        return text
    if (d == lo or d == hi) and _exact(text, lo, hi, inclusive):
        return text
    if not wide_above or d >= a:
        return None
    mantissa, _, exponent = text.partition("e")
    text = f"{int(mantissa.replace('.', '')) + 1}e{int(exponent) - p + 1}"
    d = float(text)
    if lo < d < hi or ((d == lo or d == hi) and _exact(text, lo, hi, inclusive)):
        return text
    return None


def _digits(text: str) -> int:
    """The significant digits of a candidate ("3.048000e+01": 4; "3049e-2": 4)."""
    mantissa = text[: text.index("e")].replace(".", "").rstrip("0")
    return len(mantissa) or 1


def _shortest(a: float, lo: float, hi: float, inclusive: bool, wide_above: bool) -> str:
    """The shortest decimal in [lo, hi], the nearest to `a` of those. Seven digits or fewer for the values
    people typed (their 7-digit text ends in zeros: those digits are the shortest unless fewer still
    reach), 8 or 9 for most others; a p-digit decimal in the interval is a (p+1)-digit one too, so fewer
    than the 7-digit text's own digits are searched by halves."""
    text = _candidate(a, 7, lo, hi, inclusive, wide_above)
    if text is None:
        return _candidate(a, 8, lo, hi, inclusive, wide_above) or _candidate(a, 9, lo, hi, inclusive,
                                                                               wide_above) or "%.8e" % a
    n = _digits(text)
    fewer = _candidate(a, n - 1, lo, hi, inclusive, wide_above) if n > 1 else None
    if fewer is None:
        return text
    text, low, high = fewer, 1, n - 2
    while low <= high:
        mid = (low + high) // 2
        found = _candidate(a, mid, lo, hi, inclusive, wide_above)
        if found is None:
            low = mid + 1
        else:
            text, high = found, mid - 1
    return text


def f32_value(v: float) -> float:
    """The double whose shortest text (repr, orjson) is the shortest decimal that reads back as float32 `v`
    (30.48 for the float32 nearest 30.48); NaN, infinities and zeros as they are. `v` is a float32 value
    (one `struct.unpack("<f")` gave); another double is first rounded to float32 (one beyond float32's
    range is returned as it is)."""
    hit = _CACHE.get(v)
    if hit is not None:
        return hit
    if v == 0.0 or not _isfinite(v):
        return v
    try:
        packed = _pack(v)
    except OverflowError:
        return v
    bits = _bits(packed)[0]
    a = _unpack(packed)[0]
    if a < 0:
        a = -a
    if a == 0.0:  # a double below float32's least subnormal
        return v
    exponent, mantissa = (bits >> 23) & 0xFF, bits & 0x7FFFFF
    step = _ldexp(1.0, exponent - 150) if exponent else _ldexp(1.0, -149)
    wide_above = mantissa == 0 and exponent > 1  # a power of two: the float below is half a step nearer
    lo, hi = a - (step / 4 if wide_above else step / 2), a + step / 2
    inclusive = not bits & 1  # an even significand wins the ties: the ends read back as `a`
    best = float(_shortest(a, lo, hi, inclusive, wide_above))
    result = -best if bits >> 31 else best
    if len(_CACHE) >= _CACHE_MAX:
        _CACHE.clear()
    _CACHE[v] = result
    return result


def f32_text(v: float) -> str:
    """The shortest decimal that reads back as float32 `v`, laid out as Python's repr (numpy.float32's
    repr): `30.48`, `100.0`, `-0.0`, `1e-45`, `3.4028235e+38`; NaN and infinities as repr writes them."""
    return repr(f32_value(v))


def float_text(v: float, float32: bool) -> str:
    """A MAVLink float or double value as text (`float32`: a `float` field): the shortest decimal that
    reads back as the same value (`f32_text`, or repr for a double); NaN and infinities as repr
    writes them (each output spells those its own way first)."""
    return f32_text(v) if float32 else repr(v)


def f32_shown(v: object) -> object:
    """A float32 field's decoded value as JSON and text carry it: a float as `f32_value` (its repr, orjson's
    and json's number are the shortest decimal), each float of a list (a `float[N]` array) so; anything else
    (None for a NaN an analysis made "no value", an int of a hostile dialect's field) as it is. Only for
    shown values: an analysis computes with the float32 itself (a whole number above 2**24, a PX4 custom
    mode in DO_SET_MODE's param2, reads back as itself but its shortest text is another whole number)."""
    if type(v) is float:
        return f32_value(v)
    if isinstance(v, list):
        return [f32_value(x) if type(x) is float else x for x in v]
    return v


# A message's float32 fields (name, is an array), by the MessageDef (a memo: dialects loaded again and again)
_FLOAT32: dict[int, tuple[MessageDef, frozenset[str]]] = {}


def float32_fields(md: MessageDef) -> frozenset[str]:
    """The names of `md`'s `float` (float32) fields, scalars and arrays."""
    hit = _FLOAT32.get(id(md))
    if hit is not None and hit[0] is md:
        return hit[1]
    names = frozenset(f.name for f in md.fields if f.type == "float")
    if len(_FLOAT32) >= 4096:
        _FLOAT32.clear()
    _FLOAT32[id(md)] = (md, names)
    return names


def shortest_fields(md: MessageDef | None, values: dict[str, object]) -> dict[str, object]:
    """`values` (a decoded payload, or an analysis's values keyed by field name) with each value of a
    float32 field of `md` as `f32_shown` gives it: a new dict (`values` itself when `md` has no float32
    field). Keys that are no float32 field of `md` (a double, an integer, a value the analysis computed
    under a field's name, such as COMMAND_INT's x in degrees) keep their value."""
    names = float32_fields(md) if md is not None else frozenset()
    if not names:
        return values
    return {k: f32_shown(v) if k in names else v for k, v in values.items()}
