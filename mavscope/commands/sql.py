"""`mavscope sql 'SELECT ...' DATASET_OR_FILES...`: DuckDB over export datasets, with views named
`frames`, `findings`, `anomalies`, `captures` and one per message type. Captures and directories that
are not datasets are exported to a temporary dataset first (docs/dataset.md)."""

from __future__ import annotations

import argparse
import csv
import datetime
import decimal
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from mavscope.cli import Env, ExitStatus
from mavscope.commands.common import add_dialect_option, add_key_options, pipeline_options, warner
from mavscope.commands.export import Reporter, bar, gather, needs_fleet
from mavscope.errors import UsageError
from mavscope.visible import visible

if TYPE_CHECKING:
    import pyarrow as pa

TEXT_ROWS = 10_000  # rows a text table shows at most (--json and --csv write every row)
INT_RANGE = (-(1 << 63), (1 << 64) - 1)  # the integers orjson writes (larger whole decimals: floats in JSON)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sql",
                       description="Run one SQL query (DuckDB) over datasets made by `mavscope export`, with views "
                                   "frames, findings, anomalies, captures and one per message type (HEARTBEAT, "
                                   "GLOBAL_POSITION_INT...). Captures and directories of captures are exported "
                                   "to a temporary dataset first.")
    p.add_argument("query", metavar="SQL", help="the query, e.g. \"SELECT sysid, count(*) FROM frames WHERE "
                                                 "signature_status = 'invalid' GROUP BY 1\"")
    p.add_argument("paths", nargs="+", metavar="DATASET_OR_FILE", help="export datasets, captures or directories")
    out = p.add_mutually_exclusive_group()
    out.add_argument("--json", action="store_true", help="the rows as a JSON array of objects")
    out.add_argument("--csv", action="store_true", help="the rows as CSV with a header line")
    p.add_argument("--unsafe-csv", dest="guard", action="store_false",
                   help="with --csv: write text that begins with = + - @ as it is (by default it gets a leading ' so "
                        "that a spreadsheet does not run a sender's text as a formula)")
    add_dialect_option(p)
    add_key_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    needs_fleet("pyarrow", "numpy", "duckdb")
    from mavscope.export.dataset import is_dataset

    datasets = [Path(p) for p in args.paths if is_dataset(p)]
    raw = [p for p in args.paths if not is_dataset(p)]
    with tempfile.TemporaryDirectory(prefix="mavscope-sql-") as tmp:
        if raw:
            datasets.append(_export(args, env, raw, Path(tmp) / "dataset"))
        from mavscope.export.query import connect, query

        con = connect(datasets)
        try:
            schema, batches = query(con, args.query)
            if args.json:
                _json(env, batches)
            elif args.csv:
                _csv(env, schema.names, batches, args.guard)
            else:
                _text(env, schema, batches)
        finally:
            con.close()
    return ExitStatus.OK


def _export(args: argparse.Namespace, env: Env, paths: list[str], dataset: Path) -> Path:
    import os

    from mavscope.export.run import export_local
    from mavscope.export.source import ExportOptions, source_name

    captures = gather(env, paths, tuple(args.dialect or ()))
    if not captures:
        raise UsageError("sql: no captures and no dataset among the paths given")
    # the native batch source where the extension is built, unless MAVSCOPE_PURE=1 (docs/dataset.md)
    options = ExportOptions(pipeline=pipeline_options(args, env), source=source_name("auto", env.environ))
    report = Reporter(env, errors=False)  # (the first error is the command's)
    with bar(env, sum(os.path.getsize(p) for p in captures), "exporting") as update:
        results = export_local(dataset, captures, options, on_bytes=update, warn=warner(env), on_result=report)
    report.close()
    failed = [r.error for r in results if r.status == "failed"]
    if failed:
        raise UsageError(failed[0])
    return dataset


def _plain(v: object) -> object:
    """A value as JSON carries it: bytes as hex, whole decimals (DuckDB's sums of integers, HUGEINT, come
    as decimal(38, 0)) as integers, other decimals as floats, times as ISO-8601."""
    if isinstance(v, (bytes, bytearray, memoryview)):
        return bytes(v).hex()
    if isinstance(v, decimal.Decimal):
        whole = v.is_finite() and v == v.to_integral_value()
        return int(v) if whole and INT_RANGE[0] <= v <= INT_RANGE[1] else float(v)  # (orjson: 64 bits at most)
    if isinstance(v, (datetime.datetime, datetime.date, datetime.time)):
        return v.isoformat()
    if isinstance(v, datetime.timedelta):
        return v.total_seconds()
    return v


def _default(v: object) -> object:
    out = _plain(v)
    return str(v) if out is v else out  # never raise on a type DuckDB may add


def _values(column: pa.Array) -> list[object]:
    """A result column's values: a FLOAT (float32) column's, and a list of them, as the doubles of their
    shortest decimals, which the text, CSV and JSON write as the shortest text that reads back as the same
    float32 (30.48, not 30.479999542236328: mavlink/floats.py); a DOUBLE's as they are."""
    import pyarrow as pa

    from mavscope.mavlink.floats import f32_shown

    t = column.type
    if pa.types.is_list(t) or pa.types.is_large_list(t) or pa.types.is_fixed_size_list(t):
        t = t.value_type
    return [f32_shown(v) for v in column.to_pylist()] if pa.types.is_float32(t) else column.to_pylist()


def _rows(batches: Iterator[pa.RecordBatch]) -> Iterator[dict[str, object]]:
    for b in batches:
        names = b.schema.names
        yield from (dict(zip(names, row)) for row in zip(*(_values(c) for c in b.columns)))


def _tuples(batches: Iterator[pa.RecordBatch]) -> Iterator[tuple[object, ...]]:
    """Rows as tuples (a query may name two columns alike)."""
    for b in batches:
        yield from zip(*(_values(c) for c in b.columns))


def _json(env: Env, batches: Iterator[pa.RecordBatch]) -> None:
    import orjson

    out = env.stdout_bytes
    out.write(b"[")
    first = True
    for row in _rows(batches):
        out.write((b"\n" if first else b",\n") + orjson.dumps(row, default=_default,
                                                               option=orjson.OPT_NON_STR_KEYS))
        first = False
    out.write(b"\n]\n" if not first else b"]\n")
    out.flush()


def _cell(v: object) -> str:
    """A value as the text table and CSV write it (decimals exactly, in their own scale: 9, 1.50)."""
    if v is None:
        return ""
    if isinstance(v, decimal.Decimal):
        return format(v, "f")
    if isinstance(v, (list, dict)):
        import orjson

        return orjson.dumps(v, default=_default, option=orjson.OPT_NON_STR_KEYS).decode()
    return str(_plain(v))


def _csv(env: Env, names: list[str], batches: Iterator[pa.RecordBatch], guard: bool) -> None:
    """CSV rows; `guard`: text cells a spreadsheet would run as formulas get a leading ' (counted on
    stderr), as `export -T csv` writes them (mavscope.export.csvout)."""
    from mavscope.export.csvout import guard_cells, guarded_note

    try:  # a terminal gets every cell escaped (mavscope.visible: no ESC of the capture's runs there); a file
        tty = env.stdout.isatty()  # or a pipe gets the values as they are
    except (AttributeError, ValueError):
        tty = False
    w = csv.writer(env.stdout, lineterminator="\n")
    w.writerow([visible(n) for n in names] if tty else names)
    guarded = 0
    for row in _tuples(batches):
        values = list(row)
        if guard:
            guarded += guard_cells(values)
        w.writerow([visible(_cell(v)) for v in values] if tty else [_cell(v) for v in values])
    if guarded:
        env.say(guarded_note("sql", guarded), prefix="")


def _text(env: Env, schema: pa.Schema, batches: Iterator[pa.RecordBatch]) -> None:
    import pyarrow as pa

    from mavscope.commands.common import console
    from mavscope.output.grid import Column, print_table

    cols = [Column(f.name, fold=True, right=pa.types.is_integer(f.type) or pa.types.is_floating(f.type)
                   or pa.types.is_decimal(f.type)) for f in schema]
    rows: list[tuple] = []
    total = 0
    for row in _tuples(batches):
        total += 1
        if len(rows) < TEXT_ROWS:
            rows.append(row)
    shown = len(rows)
    con = console(env)
    print_table(con, cols, rows, lambda r: ["NULL" if v is None else _cell(v) for v in r], edge=False, words=True)
    more = f" ({shown} shown: --csv or --json for all)" if total > shown else ""
    con.print(f"{total} row(s){more}", highlight=False)
