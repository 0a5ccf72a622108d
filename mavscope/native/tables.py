"""The dialect's layout table for the C extension (`_native.Table`), compiled once per Dialect object:
`read`, `stats`, the export and the TUI's index all walk with it.

The table itself is built from pymavlink's parse of the XML (mavscope.native.table_blob.build_table);
this module only keeps the compiled object, in the pipeline's layer so that the export, the browse layer
and the column-mode walk can use it (mavscope.native.walk, the front ends' engine, sits above them).
"""

from __future__ import annotations

from mavscope.mavlink.dialect import Dialect
from mavscope.native.core import _native
from mavscope.native.table_blob import build_table

_tables: list[tuple[Dialect, _native.Table]] = []  # the Dialects compiled last and their tables, the newest last
_KEPT = 8  # a process loads the default dialect once (load_dialect) and at most a few others


def table_for(dialect: Dialect) -> _native.Table:
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
