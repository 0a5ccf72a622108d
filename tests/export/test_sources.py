"""The batch-source seam: every registered source yields the declared schemas and the pure-Python
source's rows (a native decoder that registers is held to this), and sources are looked up by name."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pyarrow as pa
import pytest

from mavscope.errors import UsageError
from mavscope.export import ExportOptions, message_schema, record_batches, register_source, table_of
from mavscope.export.schema import FIXED_SCHEMAS, MESSAGE_PREFIX
from mavscope.export.source import SOURCES, dialect_for
from tests.conftest import CAPTURES

PATHS = [CAPTURES / n for n in ("px4_sitl_udp.pcap", "signed_udp.pcap", "damaged.pcap", "securemav_udp.pcap")]


def _rows(path: Path, source: str) -> dict[str, str]:
    out: dict[str, list[pa.RecordBatch]] = {}
    dialect = dialect_for(ExportOptions().pipeline)
    for b in record_batches(path, ExportOptions(source=source)):
        table = table_of(b)
        want = (message_schema(table[len(MESSAGE_PREFIX):], dialect) if table.startswith(MESSAGE_PREFIX)
                else FIXED_SCHEMAS[table]())
        assert b.schema.equals(want, check_metadata=True), (source, table)
        if table == "captures":
            b = b.drop_columns(["exported_at", "batch_source"])
        out.setdefault(table, []).append(b)
    return {t: repr(pa.Table.from_batches(bs).to_pylist()) for t, bs in out.items()}


@pytest.mark.parametrize("source", sorted(SOURCES))
@pytest.mark.parametrize("path", PATHS, ids=lambda p: p.name)
def test_every_source_gives_the_python_rows(source: str, path: Path) -> None:
    assert _rows(path, source) == _rows(path, "python")


def test_sources_by_name(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[str] = []

    def wrapped(path: str, cid: str, options: ExportOptions, progress: object,
                warn: object) -> Iterator[pa.RecordBatch]:
        seen.append(path)
        return SOURCES["python"](path, cid, options, progress, warn)  # type: ignore[arg-type]

    monkeypatch.setitem(SOURCES, "wrapped", wrapped)
    assert "wrapped" in SOURCES
    list(record_batches(PATHS[0], ExportOptions(source="wrapped")))
    assert seen == [str(PATHS[0])]
    with pytest.raises(UsageError, match="no batch source .no-such-source.*python"):
        list(record_batches(PATHS[0], ExportOptions(source="no-such-source")))
    register_source("registered", wrapped)
    try:
        assert next(record_batches(PATHS[0], ExportOptions(source="registered", tables=frozenset({"frames"}))))
    finally:
        SOURCES.pop("registered")
