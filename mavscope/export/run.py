"""Exporting many captures: hash them, leave out those already in the dataset and repeated content,
and export the rest, one capture per task: here in order (`jobs=1`), in worker processes (`jobs>1`),
or on a Dask cluster (`mavscope.export.distributed`).
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path

from mavscope.errors import MavscopeError
from mavscope.export.dataset import CaptureResult, committed_ids, export_capture, open_dataset
from mavscope.export.source import ExportOptions, Warn, content_id

OnResult = Callable[[CaptureResult], object]
OnBytes = Callable[[int], object]  # bytes of input done so far (whole captures, and within the current one)


def plan(root: Path, paths: Iterable[str], replace: bool,
         ids: dict[str, str | CaptureResult] | None = None) -> tuple[list[tuple[str, str]], list[CaptureResult]]:
    """(captures to export as (path, capture id), results decided without exporting: skipped, repeated
    content, unreadable). `ids` maps a path to its capture id when the caller hashed it (or to the
    failed result)."""
    known = committed_ids(root)
    todo: list[tuple[str, str]] = []
    done: list[CaptureResult] = []
    first: dict[str, str] = {}
    for path in paths:
        cid: str | CaptureResult
        if ids is not None and path in ids:
            cid = ids[path]
        else:
            try:
                cid = content_id(path)
            except MavscopeError as e:
                cid = CaptureResult(path, None, "failed", error=str(e))
        size = _size(path)
        if isinstance(cid, CaptureResult):
            done.append(cid)
        elif cid in first:
            done.append(CaptureResult(path, cid, "duplicate", size=size, error=f"same content as {first[cid]}"))
        elif cid in known and not replace:
            first[cid] = path
            done.append(CaptureResult(path, cid, "skipped", size=size))
        else:
            first[cid] = path
            todo.append((path, cid))
    return todo, done


def in_order(paths: list[str], results: list[CaptureResult]) -> list[CaptureResult]:
    """`results` in the order of `paths`."""
    rank = {p: i for i, p in enumerate(paths)}
    return sorted(results, key=lambda r: rank.get(r.path, len(rank)))


def _size(path: str) -> int:
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


def _with_id(options: ExportOptions, cid: str) -> ExportOptions:
    from dataclasses import replace

    return replace(options, capture_id=cid)


def export_local(dataset: str | os.PathLike[str], paths: Iterable[str], options: ExportOptions | None = None, *,
                 jobs: int = 1, replace: bool = False, durable: bool = True, on_result: OnResult | None = None,
                 on_bytes: OnBytes | None = None, warn: Warn | None = None) -> list[CaptureResult]:
    """Export `paths` into the dataset at `dataset` (created when absent), `jobs` captures at a time."""
    options = options or ExportOptions()
    root = open_dataset(dataset, create=True)
    paths = list(paths)
    todo, results = plan(root, paths, replace)
    done_bytes = 0
    for r in results:
        done_bytes += r.size
        if on_result is not None:
            on_result(r)
    if on_bytes is not None:
        on_bytes(done_bytes)

    def finished(r: CaptureResult) -> None:
        nonlocal done_bytes
        done_bytes += r.size
        results.append(r)
        if on_result is not None:
            on_result(r)
        if on_bytes is not None:
            on_bytes(done_bytes)

    if jobs <= 1 or len(todo) <= 1:
        for path, cid in todo:
            base = done_bytes
            inner = (lambda pos, base=base: on_bytes(base + pos)) if on_bytes is not None else None
            finished(export_capture(root, path, _with_id(options, cid), replace=replace, durable=durable,
                                    progress=inner, warn=warn))
        return in_order(paths, results)
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"))
    try:
        pending: set[Future[CaptureResult]] = {
            pool.submit(export_capture, str(root), path, _with_id(options, cid), replace=replace, durable=durable)
            for path, cid in todo}
        while pending:
            ready, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in ready:
                finished(fut.result())
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()
    return in_order(paths, results)
