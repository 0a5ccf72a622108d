"""The dialect's layout table for the C extension (`_native.Table`), compiled once per Dialect object:
`read`, `stats`, the export and the TUI's index all walk with it.

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

_tables: list[tuple[Dialect, object]] = []  # the Dialects compiled last and their tables, the newest last
_KEPT = 8  # a process loads the default dialect once (load_dialect) and at most a few others


def table_for(dialect: Dialect) -> object:
    """The compiled `_native.Table` of `dialect`, built once per Dialect object (the same one each time it is
    asked for again, as the objects made over it, a Summary or Columns, require)."""
    if _native is None:
        raise RuntimeError("mavscope._native is not built")
    for i, (d, table) in enumerate(_tables):
        if d is dialect:
            _tables.append(_tables.pop(i))
            return table
    if len(_tables) >= _KEPT:
        del _tables[0]
    _tables.append((dialect, _native.Table(build_table(dialect))))
    return _tables[-1][1]
