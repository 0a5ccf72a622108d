"""Scaled payload fields and their display-unit companions (docs/filters.md, "Display units").

MAVLink sends many values as scaled integers: GLOBAL_POSITION_INT.lat in degE7 (1e-7 degrees), alt in mm,
vx in cm/s, hdg in cdeg (centidegrees), voltages in mV... A filter compares the value as sent, so
`GLOBAL_POSITION_INT.lat > 40.07` is true of every latitude north of 0.000004°: mavscope warns (`warning`)
when a literal only makes sense in the display unit, and every scaled field has a companion in that unit,
named by a suffix (`lat_deg`, `alt_m`, `vx_mps`, `hdg_deg`, `voltage_battery_v`): `GLOBAL_POSITION_INT.lat_deg
> 40.07`. A companion's value is the field's divided by the scale (`473977419 / 10**7 = 47.3977419`, one
correctly rounded division), a float; it exists where the field does and a message has no field of that
name already. The units are the dialect's `units` attribute (pymavlink's parser keeps it per field).
"""

from __future__ import annotations

from dataclasses import dataclass

from mavscope.mavlink.dialect import FieldDef, MessageDef


@dataclass(frozen=True, slots=True)
class Scale:
    """A scaled unit: the display unit, the divisor (value / divisor is in the display unit), the suffix."""

    unit: str
    display: str
    divisor: int
    suffix: str
    what: str  # in words: "1e-7 degrees"


_SCALES = (
    Scale("degE7", "degrees", 10**7, "deg", "1e-7 degrees"),
    Scale("degE5", "degrees", 10**5, "deg", "1e-5 degrees"),
    Scale("cdeg", "degrees", 100, "deg", "centidegrees"),
    Scale("cdeg/s", "degrees/s", 100, "degps", "centidegrees/s"),
    Scale("mm", "m", 1000, "m", "millimetres"),
    Scale("cm", "m", 100, "m", "centimetres"),
    Scale("dm", "m", 10, "m", "decimetres"),
    Scale("mm/s", "m/s", 1000, "mps", "mm/s"),
    Scale("cm/s", "m/s", 100, "mps", "cm/s"),
    Scale("dm/s", "m/s", 10, "mps", "dm/s"),
    Scale("mrad", "rad", 1000, "rad", "milliradians"),
    Scale("mrad/s", "rad/s", 1000, "radps", "milliradians/s"),
    Scale("mV", "V", 1000, "v", "millivolts"),
    Scale("cV", "V", 100, "v", "centivolts"),
    Scale("mA", "A", 1000, "a", "milliamperes"),
    Scale("cA", "A", 100, "a", "centiamperes"),
    Scale("cdegC", "degC", 100, "degc", "centidegrees Celsius"),
    Scale("c%", "%", 100, "pct", "hundredths of a percent"),
    Scale("d%", "%", 10, "pct", "tenths of a percent"),
)
SCALES: dict[str, Scale] = {s.unit: s for s in _SCALES}
_INTEGER = frozenset({"uint8_t", "int8_t", "uint16_t", "int16_t", "uint32_t", "int32_t", "uint64_t", "int64_t"})


def scale_of(fd: FieldDef) -> Scale | None:
    """The scale of an integer field sent in a scaled unit, None for any other."""
    return SCALES.get(fd.units) if fd.type in _INTEGER else None


def companion_name(fd: FieldDef) -> str | None:
    """The display-unit companion's field name (`lat_deg`), None for a field without a scale."""
    s = scale_of(fd)
    return f"{fd.name}_{s.suffix}" if s is not None else None


def companion(md: MessageDef, name: str) -> tuple[FieldDef, Scale] | None:
    """The scaled field whose companion in `md` is called `name`, and its scale (None: no such companion, or
    the message has a real field of that name)."""
    if md.field(name) is not None:
        return None
    for fd in md.fields:
        if companion_name(fd) == name:
            s = scale_of(fd)
            assert s is not None
            return fd, s
    return None


def scaled(value: object, divisor: int) -> object:
    """A companion's value: the field's divided by its scale's divisor (elements of an array too)."""
    if isinstance(value, list):
        return [v / divisor if isinstance(v, int) else v for v in value]
    return value / divisor if isinstance(value, int) and not isinstance(value, bool) else value


def looks_displayed(fd: FieldDef, literal: int | float) -> bool:
    """Whether a number compared with scaled field `fd` only makes sense in its display unit: a fraction for
    an integer field, or, for a latitude or longitude, a number within +-180 (a raw degE7 value that small is
    within 0.000018 degrees of 0; 0 itself is a raw 0)."""
    s = scale_of(fd)
    if s is None or literal == 0:
        return False
    if isinstance(literal, float) and not literal.is_integer():
        return True
    return s.unit in ("degE7", "degE5") and abs(literal) <= 180
