"""`export --engine dask`: the same dataset as the local export, from a Dask cluster of two workers.

The cluster runs in this process (`processes=False`: workers are threads, the transport in-process),
so the test needs no network and no start-up of worker processes; the tasks are the same functions a
process cluster runs. Rows are compared table by table, sorted; `exported_at` (a wall-clock time) aside.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pyarrow as pa
import pytest
from distributed import Client, LocalCluster

from mavscope.export import ExportOptions, record_batches, table_of
from tests.conftest import CAPTURES, Cli
from tests.support.dataset import arrow_table

PATHS = [CAPTURES / n for n in ("px4_sitl_udp.pcap", "signed_udp.pcap", "px4_sitl.tlog", "damaged.pcap",
                                "serial_dump.raw", "securemav_udp.pcap")]


@pytest.fixture(scope="module")
def cluster() -> Iterator[LocalCluster]:
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as c:
        yield c


def _rows(root: Path, table: str) -> list[str]:
    t = arrow_table(root, table)
    if "exported_at" in t.column_names:
        t = t.drop_columns(["exported_at"])
    return sorted(repr(r) for r in t.to_pylist())  # repr: NaN equals NaN


def test_dask_export_gives_the_local_rows(cli: Cli, cluster: LocalCluster, tmp_path: Path) -> None:
    local, remote = tmp_path / "local", tmp_path / "dask"
    assert cli("export", *map(str, PATHS), "--parquet", str(local))[0] == 0
    status, out, err = cli("export", *map(str, PATHS), "--parquet", str(remote), "--engine", "dask",
                           "--scheduler", cluster.scheduler_address, "--json")
    assert status == 0, err
    doc = json.loads(out)
    assert [c["status"] for c in doc["captures"]] == ["exported"] * len(PATHS)
    with Client(cluster) as client:  # a cluster of two workers ran it
        assert len(client.scheduler_info()["workers"]) == 2
    tables = sorted(p.name for p in local.iterdir() if not p.name.startswith("_"))
    assert tables == sorted(p.name for p in remote.iterdir() if not p.name.startswith("_"))
    for table in tables:
        assert _rows(local, table) == _rows(remote, table), table
    # and again: everything is there already
    status, out, _ = cli("export", *map(str, PATHS), "--parquet", str(remote), "--engine", "dask",
                         "--scheduler", cluster.scheduler_address, "--json")
    assert [c["status"] for c in json.loads(out)["captures"]] == ["skipped"] * len(PATHS)


def _frames_of(path: str) -> pa.Table:
    """What a user's task runs (the function a Spark mapInArrow or Dask task calls per capture)."""
    opts = ExportOptions(tables=frozenset({"frames"}))
    return pa.Table.from_batches(list(record_batches(path, opts)))


def test_record_batches_as_tasks(cluster: LocalCluster) -> None:
    with Client(cluster) as client:
        tables = client.gather(client.map(_frames_of, [str(p) for p in PATHS[:2]]))
    for path, t in zip(PATHS, tables):
        local = pa.Table.from_batches([b for b in record_batches(path) if table_of(b) == "frames"])
        assert repr(t.to_pylist()) == repr(local.to_pylist())
