"""`export --engine dask`: the same export as tasks on a Dask cluster.

Two rounds of tasks, one task per capture each: the workers hash the captures (they read them, the
client need not), the client leaves out those already in the dataset and repeated content, and the
workers export the rest with `export_capture`, each writing its capture's partitions and committing
them as a local export does. Captures and dataset must be at the same path on every worker and on the
client (a shared file system). Without a scheduler address, a local cluster of `workers` processes.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import replace as dc_replace

from mavscope.errors import MavscopeError, UsageError
from mavscope.export.dataset import CaptureResult, export_capture, open_dataset
from mavscope.export.run import OnResult, in_order, plan
from mavscope.export.source import ExportOptions, content_id


def _hash(path: str) -> str | CaptureResult:
    try:
        return content_id(path)
    except MavscopeError as e:
        return CaptureResult(path, None, "failed", error=str(e))


def export_dask(dataset: str | os.PathLike[str], paths: Iterable[str], options: ExportOptions | None = None, *,
                scheduler: str | None = None, workers: int = 2, replace: bool = False, durable: bool = True,
                on_result: OnResult | None = None) -> list[CaptureResult]:
    """Export `paths` into the dataset at `dataset` on the Dask cluster at `scheduler` (a local cluster of
    `workers` processes without one). Paths are made absolute: the workers resolve them."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise UsageError("export --engine dask needs dask.distributed: pip install 'mavscope[fleet]'") from None
    options = options or ExportOptions()
    root = open_dataset(dataset, create=True).resolve()
    paths = [os.path.abspath(p) for p in paths]
    cluster = None
    try:
        if scheduler is None:
            cluster = LocalCluster(n_workers=max(1, workers), threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
        else:
            client = Client(scheduler)
    except (OSError, TimeoutError, ValueError) as e:
        if cluster is not None:
            cluster.close()
        raise UsageError(f"export: cannot reach the Dask scheduler {scheduler or '(local cluster)'}: {e}") from None
    try:
        hashed = client.gather(client.map(_hash, paths, pure=False))
        todo, results = plan(root, paths, replace, dict(zip(paths, hashed)))
        for r in results:
            if on_result is not None:
                on_result(r)
        futures = [client.submit(export_capture, str(root), path, dc_replace(options, capture_id=cid),
                                 replace=replace, durable=durable, pure=False) for path, cid in todo]
        for fut in as_completed(futures):
            r = fut.result()
            results.append(r)
            if on_result is not None:
                on_result(r)
        return in_order(paths, results)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
