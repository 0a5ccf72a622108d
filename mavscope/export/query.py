"""`mavscope sql`: DuckDB over export datasets, with a view per table.

Views: `frames`, `findings`, `anomalies`, `captures`, and one per message table named after the message
(`HEARTBEAT`, `GLOBAL_POSITION_INT`...). Each reads its table's Parquet files of every dataset given
(Hive partitioning, `capture_id` typed as text) and keeps only committed captures (those with a
`captures` row: an export that was interrupted leaves nothing a query sees).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator
from pathlib import Path

import duckdb
import pyarrow as pa

from mavscope.errors import DatasetError, UsageError
from mavscope.export.dataset import PART, open_dataset, tables
from mavscope.export.schema import CAPTURES, FIXED_SCHEMAS, FIXED_TABLES, MESSAGE_PREFIX, PARTITION

ROWS = 8192
EMPTY = "_empty_"  # prefix of the empty Arrow tables registered for fixed tables no capture filled
VIEWS_NAMED = 40  # views listed, at most, when a query names one there is not


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
    try:
        if CAPTURES in found:
            _view(con, CAPTURES, f"SELECT * FROM {_reader(found[CAPTURES])}")
        committed = f"WHERE {PARTITION} IN (SELECT {PARTITION} FROM {_ident(CAPTURES)})"
        for table in sorted(set(found) | set(FIXED_TABLES)):
            if table == CAPTURES and table in found:
                continue
            if table in found:
                _view(con, table, f"SELECT * FROM {_reader(found[table])} {committed}")
            else:  # an empty table of its schema, so that a query over it runs
                empty = FIXED_SCHEMAS[table]().empty_table()
                con.register(f"{EMPTY}{table}", empty)
                _view(con, table, f"SELECT * FROM {_ident(EMPTY + table)}")
    except BaseException:
        con.close()
        raise
    return con


def _view(con: duckdb.DuckDBPyConnection, table: str, select: str) -> None:
    """The view of `table` (DatasetError where DuckDB cannot read its files: a damaged or foreign Parquet
    file names itself in DuckDB's message)."""
    try:
        con.execute(f"CREATE VIEW {_ident(view_name(table))} AS {select}")
    except duckdb.Error as e:
        first = next((ln for ln in str(e).splitlines() if ln.strip()), str(e))  # not DuckDB's echo of our SQL
        raise DatasetError(f"sql: cannot read the dataset's {table} table: {first}") from None


def views(con: duckdb.DuckDBPyConnection) -> list[str]:
    """The views a query can use (not the empty tables behind those of tables without data)."""
    rows = con.execute("SELECT view_name FROM duckdb_views() WHERE NOT internal ORDER BY view_name").fetchall()
    return [r[0] for r in rows if not r[0].startswith(EMPTY)]


def query(con: duckdb.DuckDBPyConnection, sql: str) -> tuple[pa.Schema, Iterator[pa.RecordBatch]]:
    """The result of `sql` as record batches (UsageError with DuckDB's message when it fails)."""
    try:
        rel = con.sql(sql)
    except duckdb.CatalogException as e:
        raise UsageError(_missing_view(con, sql) or f"sql: {_first_line(str(e))}") from None
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


def _missing_view(con: duckdb.DuckDBPyConnection, sql: str) -> str | None:
    """"sql: no view NAME ...; views: ..." when `sql` names a table that is not a view here (a message
    table exists only when some capture has a frame of that message); None for other catalog errors."""
    try:
        row = con.execute("SELECT json_serialize_sql(?)", [sql]).fetchone()
        tree = json.loads(row[0]) if row else {}
    except (duckdb.Error, ValueError):
        return None
    named, ctes = _table_names(tree)
    have = views(con)
    known = {v.lower() for v in have} | ctes
    missing = sorted(n for n in named if n.lower() not in known)
    if not missing:
        return None
    listed = ", ".join(have[:VIEWS_NAMED]) + (f" and {len(have) - VIEWS_NAMED} more" if len(have) > VIEWS_NAMED else "")
    return (f"sql: no view {', '.join(missing)} in the dataset(s) (a message's view is there when a capture has "
            f"a frame of it); views: {listed}")


def _table_names(tree: object) -> tuple[set[str], set[str]]:
    """(tables the parsed query reads, names of its common table expressions in lower case), from DuckDB's
    own parse tree (`json_serialize_sql`): no binding, so a query that names a missing view parses."""
    named: set[str] = set()
    ctes: set[str] = set()
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, list):
            stack.extend(node)
        elif isinstance(node, dict):
            if node.get("type") == "BASE_TABLE" and isinstance(node.get("table_name"), str):
                named.add(node["table_name"])
            cte = node.get("cte_map")
            if isinstance(cte, dict):
                ctes.update(str(m.get("key", "")).lower() for m in cte.get("map", []) if isinstance(m, dict))
            stack.extend(node.values())
    return named, ctes


def _first_line(text: str) -> str:
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return " ".join(lines[:3]) if lines else text
