"""The dialect's layout table for the C extension (`_native.Table`), compiled once for the Dialect object
last asked for: `read`, `stats`, the export and the TUI's index all walk with it.

The table itself is built from pymavlink's parse of the XML (mavscope.mavlink.native_table.build_table);
this module only keeps the compiled object, in the export's layer so that the export and the browse layer
can use it (mavscope.native, the front ends' engine, sits above them).
"""

from __future__ import annotations

from types import ModuleType

from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.native_table import build_table

_native: ModuleType | None
try:
    from mavscope import _native  # type: ignore[attr-defined,no-redef]
except ImportError:  # built without a compiler
    _native = None

_table: list[tuple[Dialect, object]] = []  # the last Dialect compiled and its table (a command loads one)


def table_for(dialect: Dialect) -> object:
    """The compiled `_native.Table` of `dialect`, built once for the Dialect object last asked for."""
    if _native is None:
        raise RuntimeError("mavscope._native is not built")
    if not _table or _table[0][0] is not dialect:
        _table[:] = [(dialect, _native.Table(build_table(dialect)))]
    return _table[0][1]
