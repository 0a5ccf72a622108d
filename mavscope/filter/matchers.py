"""Tests of one field value against converted literals: the innermost closures a filter runs per frame."""

from __future__ import annotations

import ipaddress
import math
import operator
from collections.abc import Callable

# typeshed types the ordering operators for comparable values only; here they get any field value and
# the callers catch the TypeError of a mismatch.
CMP: dict[str, Callable[[object, object], bool]] = {
    "==": operator.eq, "!=": operator.ne,
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,  # type: ignore[dict-item]
}


def matcher(op: str, consts: list[object], kind: str) -> Callable[[object], bool]:
    """A test of one field value against the converted literal(s)."""
    if op == "in":
        singles = [c for c in consts if not (isinstance(c, tuple) and c and c[0] == "range")]
        ranges = [(c[1], c[2]) for c in consts if isinstance(c, tuple) and c and c[0] == "range"]
        eqs = [matcher("==", [c], kind) for c in singles]

        def in_(v: object) -> bool:
            if any(e(v) for e in eqs):
                return True
            try:
                return any(lo <= v <= hi for lo, hi in ranges)
            except TypeError:
                return False
        return in_
    c = consts[0]
    if op == "matches":
        search = c.search  # type: ignore[attr-defined]
        return lambda v: isinstance(v, str) and search(v) is not None
    if op == "contains":
        if kind == "array":
            return lambda v: v == c
        return lambda v: isinstance(v, (str, bytes)) and type(v) is type(c) and c in v  # type: ignore[operator]
    if op == "&":
        return lambda v: isinstance(v, int) and bool(v & c)  # type: ignore[operator]
    if isinstance(c, (ipaddress.IPv4Network, ipaddress.IPv6Network)):
        net = c
        if op == "==":
            return lambda v: v in net
        return lambda v: v not in net
    cmp = CMP[op]
    if isinstance(c, float) and math.isnan(c):
        return lambda v: False

    def m(v: object) -> bool:
        try:
            return bool(cmp(v, c))
        except TypeError:
            return False
    return m
