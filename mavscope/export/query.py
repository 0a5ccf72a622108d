"""`mavscope sql`: DuckDB over export datasets, with a view per table.

Views: `frames`, `findings`, `anomalies`, `captures`, and one per message table named after the message
(`HEARTBEAT`, `GLOBAL_POSITION_INT`...). Each reads its table's Parquet files of every dataset given
(Hive partitioning, `capture_id` typed as text) and keeps only committed captures (those with a
`captures` row: an export that was interrupted leaves nothing a query sees).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path

import duckdb
import pyarrow as pa

from mavscope.errors import UsageError
from mavscope.export.dataset import PART, open_dataset, tables
from mavscope.export.schema import CAPTURES, FIXED_SCHEMAS, FIXED_TABLES, MESSAGE_PREFIX, PARTITION

ROWS = 8192


def _literal(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def _ident(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def view_name(table: str) -> str:
    """The SQL view of a dataset table: the message name for `msg=NAME`, the table name otherwise."""
    return table[len(MESSAGE_PREFIX):] if table.startswith(MESSAGE_PREFIX) else table


def _reader(globs: list[str]) -> str:
    files = "[" + ", ".join(_literal(g) for g in globs) + "]"
    return (f"read_parquet({files}, hive_partitioning = true, hive_types = {{'{PARTITION}': VARCHAR}}, "
            "union_by_name = true)")


def connect(datasets: Iterable[Path]) -> duckdb.DuckDBPyConnection:
    """An in-memory DuckDB connection with the views of `datasets` (DatasetError for a directory that is
    not a dataset of this schema version)."""
    roots = [open_dataset(d, create=False) for d in datasets]
    found: dict[str, list[str]] = {}
    for root in roots:
        for table in tables(root):
            if any((root / table).glob(f"{PARTITION}=*/{PART}")):
                found.setdefault(table, []).append(str(root / table / f"{PARTITION}=*" / PART))
    con = duckdb.connect(":memory:")
    if CAPTURES in found:
        con.execute(f"CREATE VIEW {_ident(CAPTURES)} AS SELECT * FROM {_reader(found[CAPTURES])}")
    committed = f"WHERE {PARTITION} IN (SELECT {PARTITION} FROM {_ident(CAPTURES)})"
    for table in sorted(set(found) | set(FIXED_TABLES)):
        if table == CAPTURES and table in found:
            continue
        view = _ident(view_name(table))
        if table in found:
            con.execute(f"CREATE VIEW {view} AS SELECT * FROM {_reader(found[table])} {committed}")
        else:  # an empty table of its schema, so that a query over it runs
            empty = FIXED_SCHEMAS[table]().empty_table()
            con.register(f"_empty_{table}", empty)
            con.execute(f"CREATE VIEW {view} AS SELECT * FROM {_ident('_empty_' + table)}")
    return con


def views(con: duckdb.DuckDBPyConnection) -> list[str]:
    rows = con.execute("SELECT view_name FROM duckdb_views() WHERE NOT internal ORDER BY view_name").fetchall()
    return [r[0] for r in rows]


def query(con: duckdb.DuckDBPyConnection, sql: str) -> tuple[pa.Schema, Iterator[pa.RecordBatch]]:
    """The result of `sql` as record batches (UsageError with DuckDB's message when it fails)."""
    try:
        rel = con.sql(sql)
    except duckdb.Error as e:
        raise UsageError(f"sql: {_first_line(str(e))}") from None
    if rel is None:
        return pa.schema([]), iter(())
    try:
        reader = rel.to_arrow_reader(ROWS)
    except duckdb.Error as e:
        raise UsageError(f"sql: {_first_line(str(e))}") from None

    def batches() -> Iterator[pa.RecordBatch]:
        try:
            yield from reader
        except (duckdb.Error, pa.ArrowException) as e:
            raise UsageError(f"sql: {_first_line(str(e))}") from None

    return reader.schema, batches()


def _first_line(text: str) -> str:
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return " ".join(lines[:3]) if lines else text
