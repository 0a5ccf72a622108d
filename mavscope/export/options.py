"""What an export runs (`ExportOptions`), the shape of a batch source, and the dialect loaded once per process.

The batch sources (`pure.py`, `native.py`) and the registry that names them (`source.py`) share these.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import lru_cache

import pyarrow as pa

from mavscope.export.columns import DEFAULT_ROWS
from mavscope.export.schema import MESSAGE_PREFIX
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.pipeline.options import PipelineOptions

Progress = Callable[[int], object]  # called with the capture's file offset reached so far
Warn = Callable[[str], object]
AUTO = "auto"  # the native source where the C extension is built and MAVSCOPE_PURE is not set, else python


@dataclass(frozen=True, slots=True)
class ExportOptions:
    """What an export runs: the pipeline's options (dialects, key material; no display filter), the
    rows per record batch, the tables wanted (None: all) and the batch source ("auto", "native",
    "python", or another registered one)."""

    pipeline: PipelineOptions = field(default_factory=PipelineOptions)
    batch_rows: int = DEFAULT_ROWS
    tables: frozenset[str] | None = None  # {"frames"}, {"msg=HEARTBEAT"}...; "msg=*" for every message table
    source: str = AUTO
    capture_id: str | None = None  # the capture's SHA-256 when the caller has it already

    def wants(self, table: str) -> bool:
        t = self.tables
        return t is None or table in t or (table.startswith(MESSAGE_PREFIX) and "msg=*" in t)

    @property
    def wants_messages(self) -> bool:
        t = self.tables
        return t is None or any(x.startswith(MESSAGE_PREFIX) for x in t)


# A batch source: (path, capture id, options, progress, warn) -> the capture's record batches
BatchSource = Callable[[str, str, ExportOptions, Progress | None, Warn | None], Iterator[pa.RecordBatch]]

_dialect_lock = threading.Lock()  # pymavlink's parser and its stdout redirection are not thread-safe


@lru_cache(maxsize=8)
def _dialect(files: tuple[str, ...]) -> Dialect:
    return load_dialect(files)


def dialect_for(options: PipelineOptions) -> Dialect:
    """The dialect of `options`, loaded once per process (Dask workers run many captures each)."""
    with _dialect_lock:
        return _dialect(tuple(options.dialects))
