"""`export -T csv`: mavlogdump-style CSV, one file per message type and capture.

As `mavlogdump.py --format csv --types MSG` writes it: a header `timestamp,MSG.field,...` (fields in
XML order), then one line per frame: the capture time with 8 decimals, then each value as Python's
`str()` writes it (arrays as `[1, 2, 3]`, which the CSV quotes; char arrays as their text). Only frames
whose CRC verifies, as pymavlink gives them. The rows come from the same record batches as the
dataset (`record_batches`, message tables only), so the CSV and the Parquet agree.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import IO, Any

import pyarrow.compute as pc

from mavscope.export.schema import CAPTURES, IDENTITY, MESSAGE_PREFIX, message_columns, table_of
from mavscope.export.source import ExportOptions, Progress, Warn, dialect_for, record_batches

_SKIP = 1 + len(IDENTITY)  # capture_id and the frame identity come before the fields


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


def write_capture_csv(path: str, folder: Path, options: ExportOptions | None = None, *,
                      progress: Progress | None = None, warn: Warn | None = None) -> CsvCapture:
    """The CSV files of the capture at `path` in `folder` (created)."""
    options = replace(options or ExportOptions(), tables=frozenset({"msg=*", CAPTURES}))
    dialect = dialect_for(options.pipeline)
    folder.mkdir(parents=True, exist_ok=True)
    files: dict[str, tuple[IO[str], Any]] = {}
    counts: dict[str, int] = {}
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
                f: IO[str] = open(folder / f"{name}.csv", "w", newline="", encoding="utf-8")  # noqa: SIM115
                w = csv.writer(f, lineterminator="\n")
                w.writerow(["timestamp"] + [f"{name}.{fd.name}" for _, fd in cols.fields])
                entry = files[name] = (f, w)
            writer = entry[1]
            ok = pc.equal(batch.column("_crc_status"), "ok")
            rows = batch.filter(ok)
            times = rows.column("_time").to_pylist()
            values = [rows.column(_SKIP + j).to_pylist() for j in range(len(cols.fields))]
            for i, t in enumerate(times):
                writer.writerow(["" if t is None else f"{t:.8f}"] + [_text(v[i]) for v in values])
            counts[name] = counts.get(name, 0) + len(times)
    finally:
        for f, _ in files.values():
            f.close()
    return replace(said, counts=counts)


def csv_folder(out: Path, path: str, taken: set[str]) -> Path:
    """The folder of a capture's CSV files: its file name, with a number added when another capture of
    this export has that name."""
    base = os.path.basename(os.fsencode(path)).decode("utf-8", "backslashreplace") or "capture"
    name, n = base, 1
    while name in taken:
        n += 1
        name = f"{base}.{n}"
    taken.add(name)
    return out / name
