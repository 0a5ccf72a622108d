"""`record_batches(path, options)`: one capture as Arrow record batches of every dataset table.

This is the one function every engine runs per capture: the local exporter, its worker processes
(`-j N`), a Dask task, or a Spark `mapInArrow` (docs/dataset.md). Each batch says which table it
belongs to in its schema metadata (`table_of(batch)`); `ExportOptions.tables` keeps only some tables
(Spark wants one schema per output).

Where batches come from is a *batch source*, looked up by name in `SOURCES`: `python` (export/pure.py)
runs the session (dissector and security stage), the expert, audit, objects and params analyses and the
column builders in one pass; `native` (export/native.py) takes the clean records' columns from the C
extension in bulk and hands the rest to the same Python pipeline. `auto`, the default, is `native` where
the extension is built and MAVSCOPE_PURE is not set, else `python`. Every source yields the same tables
with the same schemas and rows; the test suite runs its contract over every registered source. Another
source registers itself with `register_source(name, source)`.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterator, Mapping

import pyarrow as pa

from mavscope.capture.reader import open_file, pread
from mavscope.errors import CaptureError, UsageError
from mavscope.export.options import AUTO, BatchSource, ExportOptions, Progress, Warn, dialect_for
from mavscope.export.pure import PYTHON, python_source
from mavscope.export.schema import table_of
from mavscope.native import export as native
from mavscope.native.core import available

__all__ = ["SOURCES", "BatchSource", "ExportOptions", "Progress", "Warn", "content_id", "dialect_for",
           "record_batches", "register_source", "source_name"]

HASH_CHUNK = 1 << 20
SOURCES: dict[str, BatchSource] = {}


def register_source(name: str, source: BatchSource) -> None:
    """Make a batch source available as `ExportOptions(source=name)`."""
    SOURCES[name] = source


def content_id(path: str | os.PathLike[str]) -> str:
    """The capture id: SHA-256 of the file's bytes, in hex (CaptureError as `read` gives it)."""
    h = hashlib.sha256()
    spath, f, _ = open_file(path)
    try:
        offset = 0
        while chunk := pread(f, HASH_CHUNK, offset):
            h.update(chunk)
            offset += len(chunk)
    except OSError as e:
        raise CaptureError(f"cannot read: {e.strerror or e}", path=spath) from None
    finally:
        f.close()
    return h.hexdigest()


def source_name(name: str, environ: Mapping[str, str] | None = None) -> str:
    """The source `name` runs: `auto` is `native` where the extension is built and MAVSCOPE_PURE is not set."""
    if name != AUTO:
        return name
    return native.NATIVE if available(environ) else PYTHON


def record_batches(path: str | os.PathLike[str], options: ExportOptions | None = None, *,
                   progress: Progress | None = None, warn: Warn | None = None) -> Iterator[pa.RecordBatch]:
    """Every table of the capture at `path` as record batches (each with a `capture_id` column, and
    its table in the schema metadata: `mavscope.export.table_of(batch)`), in bounded memory.

    Frames come in capture order, message tables as their rows fill a batch, then findings,
    anomalies not yet given, and last one `captures` row. CaptureError, UsageError and FilterError
    as `mavscope read` raises them."""
    options = options or ExportOptions()
    if options.batch_rows < 1:
        raise UsageError(f"export: batch_rows must be at least 1, not {options.batch_rows}")
    name = source_name(options.source)
    source = SOURCES.get(name)
    if source is None:
        raise UsageError(f"export: no batch source {options.source!r} (available: {', '.join(sorted(SOURCES))})")
    spath = os.fspath(path) if not isinstance(path, bytes) else os.fsdecode(path)
    cid = options.capture_id or content_id(spath)
    for batch in source(spath, cid, options, progress, warn):
        if options.wants(table_of(batch)):
            yield batch


register_source(PYTHON, python_source)
register_source(native.NATIVE, native.native_source)
