"""Every table of one capture from a batch source, and the check that every other registered source gives
the pure-Python source's rows (tests/export/test_sources.py; the `export` fuzz target, tests/fuzz).

Tables are compared whole: each batch's schema against the declared one (metadata included), every row of
every table, floats by their bit patterns (NaN payloads, -0.0), the captures row without its export time and
source name.
"""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa

from mavscope.export import ExportOptions, message_schema, record_batches, table_of
from mavscope.export.schema import FIXED_SCHEMAS, MESSAGE_PREFIX
from mavscope.export.source import SOURCES, dialect_for
from mavscope.pipeline.options import PipelineOptions


def others() -> list[str]:
    """The registered sources other than the reference."""
    return sorted(s for s in SOURCES if s != "python")


def _bits(t: pa.DataType) -> pa.DataType | None:
    """The unsigned integer type of the same width as a float type (lists of floats too)."""
    if pa.types.is_float32(t):
        return pa.uint32()
    if pa.types.is_float64(t):
        return pa.uint64()
    if pa.types.is_list(t):
        inner = _bits(t.value_type)
        return None if inner is None else pa.list_(inner)
    return None


def _rows(table: pa.Table) -> list[dict[str, object]]:
    """The table's rows, floats as their bit patterns (so NaN equals NaN when its bits do)."""
    cols = []
    for f, col in zip(table.schema, table.columns):
        bits = _bits(f.type)
        cols.append(col if bits is None else pa.chunked_array([c.view(bits) for c in col.chunks], bits))
    return pa.table(cols, names=table.column_names).to_pylist()


def tables(path: str | Path, source: str, pipeline: PipelineOptions | None = None,
           rows: int = 65_536) -> dict[str, list[dict[str, object]]]:
    """Every table of the capture from `source`: each batch checked against its declared schema."""
    out: dict[str, list[pa.RecordBatch]] = {}
    pipeline = pipeline or PipelineOptions()
    dialect = dialect_for(pipeline)
    captures = []
    for b in record_batches(path, ExportOptions(pipeline=pipeline, source=source, batch_rows=rows)):
        table = table_of(b)
        want = (message_schema(table[len(MESSAGE_PREFIX):], dialect) if table.startswith(MESSAGE_PREFIX)
                else FIXED_SCHEMAS[table]())
        assert b.schema.equals(want, check_metadata=True), (source, table)
        if source != "python" and (table == "frames" or table.startswith(MESSAGE_PREFIX)):
            assert b.num_rows <= rows, (table, b.num_rows)
        if table == "captures":
            captures += b.column("batch_source").to_pylist()
            b = b.drop_columns(["exported_at", "batch_source"])
        out.setdefault(table, []).append(b)
    assert captures == [source]
    return {t: _rows(pa.Table.from_batches(bs)) for t, bs in out.items()}


def same_tables(path: str | Path, pipeline: PipelineOptions | None = None, rows: int = 65_536) -> None:
    want = tables(path, "python", pipeline)
    for source in others():
        got = tables(path, source, pipeline, rows)
        assert sorted(got) == sorted(want), source
        for name in want:
            assert got[name] == want[name], (source, name)
