"""Fields over time, bucketed as Wireshark's I/O graph does: per interval the count, minimum, maximum and
mean of a field's values (for `mavscope plot` and the TUI's plot screen).

`field_getter(registry, expr)` resolves a field name of the registry (`GLOBAL_POSITION_INT.relative_alt`,
a bare `relative_alt` for every message that has it, `BATTERY_STATUS.voltages[0]` for an array element,
`mavlink.seq`, `signature.skew`...) to a function giving a frame's value (None where the frame has none).
`Series` accumulates (x, value) in at most MAX_BUCKETS buckets whatever the capture's length: with no
interval given the buckets start at START_WIDTH seconds and double in width (merging pairs) whenever a
value falls beyond them; with an interval they keep it until the capture outgrows MAX_BUCKETS of them, and
then double too (`interval` says the width in effect). x is capture time from the first frame, or the frame
number when the capture has no times. Minimum and maximum survive any merging, so a spike is never lost.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

from mavscope.errors import UsageError
from mavscope.fields.registry import BY_NAME, FLOAT, INT, MISSING, Field, FieldRegistry, PayloadField
from mavscope.mavlink.floats import f32_value
from mavscope.mavlink.frame import Frame, decode_payload

MAX_BUCKETS = 1024
START_WIDTH = 0.001  # s
NUMERIC_TYPES = frozenset({"float", "double", "int8_t", "uint8_t", "int16_t", "uint16_t", "int32_t", "uint32_t",
                           "int64_t", "uint64_t", "uint8_t_mavlink_version"})
_INDEX = re.compile(r"^(?P<name>[^\[\]]+)\[(?P<index>\d{1,4})\]$")

Getter = Callable[[Frame], float | None]


def _number(v: object) -> float | None:
    """The value as a float (NaN and infinities too: the series counts them apart), None if not a number."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v)


def field_getter(registry: FieldRegistry, expr: str) -> tuple[Getter, str]:
    """(value of `expr` in a frame, its units) for a numeric field; UsageError for anything else."""
    m = _INDEX.match(expr.strip())
    name, index = (m["name"], int(m["index"])) if m else (expr.strip(), None)
    found = registry.lookup(name)
    if isinstance(found, Field):
        if index is not None or found.type not in (INT, FLOAT) or found.multi:
            raise UsageError(f"plot: {expr}: not a numeric field (type {found.type})")
        get = found.get

        def registered(f: Frame) -> float | None:
            v = get(f)
            return None if v is MISSING else _number(v)
        return registered, ""
    if not isinstance(found, PayloadField):
        what = "a message, not a field" if found is not None else "no such field"
        hint = "" if found is not None or name in BY_NAME else " (MESSAGE.field, e.g. GLOBAL_POSITION_INT.relative_alt)"
        raise UsageError(f"plot: {expr}: {what}{hint}")
    defs = found.defs
    for fd in defs.values():
        if fd.type not in NUMERIC_TYPES:
            raise UsageError(f"plot: {expr}: {fd.filter_name} is {fd.type}, not a number")
        if fd.array_length and index is None:
            raise UsageError(f"plot: {expr}: {fd.filter_name} is an array of {fd.array_length}: give an element, "
                             f"{fd.filter_name}[0]")
        if index is not None and not (fd.array_length and index < fd.array_length):
            raise UsageError(f"plot: {expr}: {fd.filter_name} has no element {index}")
    names = {msgid: (fd.message, fd.name) for msgid, fd in defs.items()}
    # a float32 field's values as the doubles of their shortest decimals (mavlink/floats.py): the minimum and
    # maximum are values of the field, shown as such (30.48, not 30.479999542236328); a mean moves by less
    # than half a float32 step
    float32 = frozenset(msgid for msgid, fd in defs.items() if fd.type == "float")
    units = {fd.units for fd in defs.values()}

    def payload(f: Frame) -> float | None:
        want = names.get(f.msgid)
        if want is None or f.msgdef is None or f.msgdef.name != want[0]:
            return None
        fields = decode_payload(f)
        if fields is None:
            return None
        v = fields.get(want[1])
        if index is not None:
            v = v[index] if isinstance(v, list) and index < len(v) else None
        return f32_value(v) if type(v) is float and f.msgid in float32 else _number(v)
    return payload, units.pop() if len(units) == 1 else ""


@dataclass
class Bucket:
    count: int
    total: float
    low: float
    high: float

    def merge(self, other: Bucket | None) -> Bucket:
        if other is None:
            return self
        return Bucket(self.count + other.count, self.total + other.total, min(self.low, other.low),
                      max(self.high, other.high))


class Series:
    """One field's values in time buckets (see the module docstring)."""

    def __init__(self, name: str, units: str = "", interval: float | None = None) -> None:
        if interval is not None and not (interval > 0 and math.isfinite(interval)):
            raise UsageError(f"plot: --interval must be a positive number of seconds, not {interval}")
        self.name = name
        self.units = units
        self.width = interval if interval is not None else START_WIDTH
        self.buckets: list[Bucket | None] = []
        self.count = 0
        self.not_finite = 0  # NaN and infinite values seen (not plotted: they have no place on the axis)
        self.low = math.inf
        self.high = -math.inf
        self.total = 0.0

    def add(self, x: float, value: float) -> None:
        """A value at `x` (units from the origin of the series' x axis, never negative)."""
        i = int(x / self.width) if x > 0 else 0
        while i >= MAX_BUCKETS:
            self.width *= 2
            b = self.buckets
            merged: list[Bucket | None] = []
            for k in range(0, len(b), 2):
                first, second = b[k], b[k + 1] if k + 1 < len(b) else None
                merged.append(second if first is None else first.merge(second))
            self.buckets = merged
            i //= 2
        if i >= len(self.buckets):
            self.buckets.extend([None] * (i + 1 - len(self.buckets)))
        old = self.buckets[i]
        self.buckets[i] = Bucket(1, value, value, value) if old is None else \
            Bucket(old.count + 1, old.total + value, min(old.low, value), max(old.high, value))
        self.count += 1
        self.total += value
        self.low = min(self.low, value)
        self.high = max(self.high, value)

    def to_json(self) -> dict[str, object]:
        return {
            "field": self.name, "units": self.units, "interval": self.width, "count": self.count,
            "not_finite": self.not_finite,
            "min": self.low if self.count else None, "max": self.high if self.count else None,
            "mean": self.total / self.count if self.count else None,
            "buckets": [{"start": round(i * self.width, 9), "count": b.count, "min": b.low, "max": b.high,
                         "avg": b.total / b.count} for i, b in enumerate(self.buckets) if b is not None],
        }


class Plotter:
    """Every series over the frames of a capture: `add(frame)` in capture order (the frames a filter keeps,
    if any), then `series`. `x_label` is "s" (capture time from the first frame) or "frame"."""

    def __init__(self, registry: FieldRegistry, exprs: list[str], interval: float | None = None) -> None:
        self.getters = []
        self.series = []
        for expr in exprs:
            get, units = field_getter(registry, expr)
            self.getters.append(get)
            self.series.append(Series(expr, units, interval))
        self.origin: float | None = None
        self.x_label: str | None = None
        self.start: float | None = None  # capture time of x = 0

    def add(self, f: Frame) -> None:
        if self.x_label is None:
            self.x_label = "s" if f.time is not None else "frame"
        if self.x_label == "s":
            if f.time is None or not math.isfinite(f.time):
                return
            pos = f.time
        else:
            pos = float(f.record)
        if self.origin is None:
            self.origin = pos
            self.start = f.time
        x = pos - self.origin
        for get, s in zip(self.getters, self.series):
            v = get(f)
            if v is None:
                continue
            if math.isfinite(v):
                s.add(x, v)
            else:
                s.not_finite += 1
