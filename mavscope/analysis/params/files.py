"""Parameter files: write the parameters as MAVProxy and Mission Planner (`.param`) and QGroundControl
(`.params`) save them, and read such files back (for `params --diff FILE`).

- `.param`: one `NAME,VALUE` per line, sorted by name, `#` comments. Mission Planner writes a comma,
  MAVProxy (pymavlink `mavparm.MAVParmDict.save`) a space and a padded name; both load either (MAVProxy's
  loader turns commas into spaces and splits; Mission Planner's splits on commas, spaces and tabs).
- `.params`: QGroundControl's `ParameterManager` format: `#` comment lines ending with
  `# Vehicle-Id Component-Id Name Value Type`, then one tab-separated line per parameter with the
  vehicle's system id, the component id, the name, the value and its MAV_PARAM_TYPE.

Names that would break a line (spaces, commas, tabs, `#`, anything outside A-Z, 0-9 and `_`) are left
out and reported. Floats are written as the shortest decimal that reads back as the same float32.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from mavscope.analysis.params.model import Component
from mavscope.analysis.params.values import REAL32, Value, value_text
from mavscope.visible import visible

NAME = re.compile(r"^[A-Za-z0-9_]{1,16}$")
QGC_HEADER = "# Vehicle-Id Component-Id Name Value Type"


class ParamFileError(ValueError):
    """Text that is not a parameter file (with the line that shows it)."""


def writable(name: str) -> bool:
    return NAME.match(name) is not None


def param_file(params: dict[str, Value], header: Iterable[str] = ()) -> tuple[str, list[str]]:
    """A Mission Planner/MAVProxy `.param` file, and the names left out."""
    lines = [f"# {visible(h)}" for h in header]  # (a capture's file name may hold a line break)
    left_out = []
    for name in sorted(params):
        v = params[name]
        if not writable(name) or isinstance(v, str):
            left_out.append(name)
            continue
        lines.append(f"{name},{value_text(v)}")
    return "\n".join(lines) + "\n", left_out


def qgc_file(components: Iterable[Component], header: Iterable[str] = ()) -> tuple[str, list[str]]:
    """A QGroundControl `.params` file of every parameter of `components`, and the names left out."""
    comps = list(components)
    vehicle = comps[0].addr[0] if comps else 1
    lines = [f"# Onboard parameters for Vehicle {vehicle}", "#"]
    lines += [f"# {visible(h)}" for h in header] + ["#", QGC_HEADER]  # (as param_file's)
    left_out = []
    for c in comps:
        for name in sorted(c.params):
            p = c.params[name]
            if not writable(name) or isinstance(p.value, str):
                left_out.append(f"{c.addr[0]}/{c.addr[1]} {name}")
                continue
            ptype = p.type if p.type is not None and 1 <= p.type <= 10 else REAL32
            lines.append(f"{c.addr[0]}\t{c.addr[1]}\t{name}\t{value_text(p.value)}\t{ptype}")
    return "\n".join(lines) + "\n", left_out


def read_param_text(text: str) -> dict[tuple[int, int] | None, dict[str, Value]]:
    """The parameters of a `.param` (key None) or `.params` (key (system, component)) file's text."""
    out: dict[tuple[int, int] | None, dict[str, Value]] = {}
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split("\t")
        if len(parts) == 5:
            key: tuple[int, int] | None = None
            try:
                key = (int(parts[0]), int(parts[1]))
                name, value = parts[2].strip(), _number(parts[3].strip())
            except ValueError:
                raise ParamFileError(f"line {number}: {line[:80]!r} is not a parameter line") from None
        else:
            fields = line.replace(",", " ").split()
            if len(fields) != 2:
                raise ParamFileError(f"line {number}: {line[:80]!r} is not NAME VALUE")
            key, name = None, fields[0]
            try:
                value = _number(fields[1])
            except ValueError:
                raise ParamFileError(f"line {number}: {fields[1][:40]!r} is not a number") from None
        if not writable(name):
            raise ParamFileError(f"line {number}: {name[:40]!r} is not a parameter name")
        out.setdefault(key, {})[name] = value
    if not out:
        raise ParamFileError("no parameter lines")
    return out


def _number(text: str) -> Value:
    if text.lower().startswith(("0x", "-0x")):
        return int(text, 16)
    try:
        return int(text)
    except ValueError:
        return float(text)
