"""Captures into one columnar dataset (Parquet, Hive-partitioned by capture) for DuckDB, Spark, Polars or
pandas: docs/dataset.md. The modules that build Arrow data need pyarrow and numpy (the fleet extra);
the public names (`record_batches`, `ExportOptions`, the schemas...) are imported from them on first
use, so that `mavscope.export.inputs` (which files of a directory are captures) works without it."""

from __future__ import annotations

import importlib

_PUBLIC = {
    "ExportOptions": "mavscope.export.source",
    "content_id": "mavscope.export.source",
    "record_batches": "mavscope.export.source",
    "register_source": "mavscope.export.source",
    "SCHEMA_VERSION": "mavscope.export.schema",
    "frames_schema": "mavscope.export.schema",
    "message_schema": "mavscope.export.schema",
    "signed_batch": "mavscope.export.schema",
    "signed_schema": "mavscope.export.schema",
    "table_of": "mavscope.export.schema",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str) -> object:
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'mavscope.export' has no attribute {name!r}")
    try:
        return getattr(importlib.import_module(module), name)
    except ImportError as exc:
        if exc.name in ("pyarrow", "numpy"):
            raise ImportError(f"mavscope.export needs {exc.name}: pip install 'mavscope[fleet]'") from exc
        raise
