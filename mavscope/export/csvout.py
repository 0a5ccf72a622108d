"""`export -T csv`: mavlogdump-style CSV, one file per message type and capture.

As `mavlogdump.py --format csv --types MSG` writes it: a header `timestamp,MSG.field,...` (fields in
XML order), then one line per frame: the capture time with 8 decimals, then each value as Python's
`str()` writes it (arrays as `[1, 2, 3]`, which the CSV quotes; char arrays as their text), but a float32
(a `float` field) as the shortest text that reads back as the same float32 (30.48 where mavlogdump writes
the double 30.479999542236328; mavlink/floats.py). Only frames whose CRC verifies, as pymavlink gives
them. The rows come from the same record batches as the dataset (`record_batches`, message tables only),
so the CSV and the Parquet agree.

One difference from mavlogdump, for safety: the text comes from whoever sent the frames, and a
spreadsheet runs a cell that begins with `=`, `+`, `-`, `@`, a tab or a carriage return as a formula
(`=HYPERLINK(...)` sends data away, `=cmd|...` ran programs in older Excel). Such a text cell is written
with a leading `'` (OWASP's advice; a spreadsheet then shows the text as it is), and the command says
how many; `guard=False` (`--unsafe-csv`) writes them as they are. Numbers are never changed.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, Any

import pyarrow.compute as pc

from mavscope.export.dataset import inside
from mavscope.export.schema import CAPTURES, IDENTITY, MESSAGE_PREFIX, message_columns, table_of
from mavscope.export.source import ExportOptions, Progress, Warn, dialect_for, record_batches
from mavscope.mavlink.dialect import FieldDef
from mavscope.mavlink.floats import f32_shown

_SKIP = 1 + len(IDENTITY)  # capture_id and the frame identity come before the fields


FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")  # what makes a spreadsheet read a cell as a formula


def _number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def formula_like(s: str) -> bool:
    """Whether a spreadsheet would read the text `s` as a formula (a signed number, `-3.5`, is a number)."""
    return s.startswith(FORMULA_STARTS) and not (s[0] in "+-" and _number(s))


def guard_cells(values: list[object]) -> int:
    """Give each text value of `values` that a spreadsheet would run as a formula a leading `'`, in place;
    how many were changed."""
    changed = 0
    for k, x in enumerate(values):
        if isinstance(x, str) and formula_like(x):
            values[k] = "'" + x
            changed += 1
    return changed


def guarded_note(command: str, cells: int) -> str:
    """The line a command writes on stderr when it guarded `cells` text cells."""
    return (f"{command}: {cells:,} text cell(s) began with = + - @, a tab or a carriage return, which a spreadsheet "
            "runs as a formula: written with a leading ' (--unsafe-csv writes them as they are)")


def _shown(column: list[object], fd: FieldDef) -> list[object]:
    """A column's values as written: a float32 field's as the doubles of their shortest decimals, which
    `str()` writes as the shortest text that reads back as the same float32 (30.48, not mavlogdump's
    30.479999542236328: mavlink/floats.py), arrays' elements too; NaN and infinities as `str()` writes them."""
    return [f32_shown(v) for v in column] if fd.type == "float" else column


def _text(v: object) -> str:
    if v is None:
        return ""  # an extension field of a MAVLink 1 frame: not on the wire
    return str(v)


@dataclass(frozen=True, slots=True)
class CsvCapture:
    """What `write_capture_csv` wrote of a capture, and what reading it said (the captures table's row)."""

    counts: dict[str, int] = field(default_factory=dict)  # message -> rows written
    frames: int = 0
    problems: int = 0  # the problems `read` reports on stderr
    first_problem: str = ""
    guarded: int = 0  # text cells written with a leading ' (`formula_like`)


def write_capture_csv(path: str, folder: Path, options: ExportOptions | None = None, *,
                      progress: Progress | None = None, warn: Warn | None = None,
                      guard: bool = True) -> CsvCapture:
    """The CSV files of the capture at `path` in `folder` (created); `guard`: text cells a spreadsheet
    would run as formulas get a leading `'` (the module's docstring)."""
    options = replace(options or ExportOptions(), tables=frozenset({"msg=*", CAPTURES}))
    dialect = dialect_for(options.pipeline)
    folder.mkdir(parents=True, exist_ok=True)
    files: dict[str, tuple[IO[str], Any]] = {}
    counts: dict[str, int] = {}
    guarded = 0
    said = CsvCapture()
    try:
        for batch in record_batches(path, options, progress=progress, warn=warn):
            if table_of(batch) == CAPTURES:
                row = batch.to_pylist()[0]
                said = CsvCapture(frames=row["frame_count"], problems=row["problem_count"] or 0,
                                  first_problem=row["first_problem"] or "")
                continue
            name = table_of(batch)[len(MESSAGE_PREFIX):]
            md = dialect.by_name[name]
            cols = message_columns(md, dialect)
            entry = files.get(name)
            if entry is None:
                f: IO[str] = open(inside(folder, f"{name}.csv"), "w", newline="", encoding="utf-8")  # noqa: SIM115
                w = csv.writer(f, lineterminator="\n")
                w.writerow(["timestamp"] + [f"{name}.{fd.name}" for _, fd in cols.fields])
                entry = files[name] = (f, w)
            writer = entry[1]
            ok = pc.equal(batch.column("_crc_status"), "ok")
            rows = batch.filter(ok)
            times = rows.column("_time").to_pylist()
            values = [_shown(rows.column(_SKIP + j).to_pylist(), fd) for j, (_, fd) in enumerate(cols.fields)]
            if guard:
                guarded += sum(guard_cells(v) for v in values)
            for i, t in enumerate(times):
                writer.writerow(["" if t is None else f"{t:.8f}"] + [_text(v[i]) for v in values])
            counts[name] = counts.get(name, 0) + len(times)
    finally:
        for f, _ in files.values():
            f.close()
    return replace(said, counts=counts, guarded=guarded)


def csv_folder(out: Path, path: str, taken: set[str]) -> Path:
    """The folder of a capture's CSV files: its file name, with a number added when another capture of
    this export has that name."""
    base = os.path.basename(os.fsencode(path)).decode("utf-8", "backslashreplace") or "capture"
    name, n = base, 1
    while name in taken:
        n += 1
        name = f"{base}.{n}"
    taken.add(name)
    return inside(out, name)
