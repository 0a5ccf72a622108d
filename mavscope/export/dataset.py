"""An export dataset on disk: its manifest and version, and the atomic write of one capture.

    DATASET/_mavscope_dataset.json           format and schema version
    DATASET/frames/capture_id=<sha256>/part-0.parquet
    DATASET/msg=HEARTBEAT/capture_id=<sha256>/part-0.parquet
    DATASET/findings/..., anomalies/..., captures/...

A capture is written into `DATASET/_staging/` first; when every table is written, each partition
is renamed into place and the `captures` partition last: a capture is in the dataset (and skipped
by the next export) exactly when its `captures` partition is. A crash leaves a staging folder
and perhaps some partitions without a `captures` row; readers ignore those (`committed_ids`), and
the next export of that capture removes them first.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from dataclasses import replace as dc_replace
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from mavscope import __version__
from mavscope.errors import DatasetError
from mavscope.export.schema import CAPTURES, FIXED_TABLES, MESSAGE_PREFIX, PARTITION, SCHEMA_VERSION, table_of
from mavscope.export.source import ExportOptions, Progress, Warn, content_id, record_batches
from mavscope.mavlink.dialect_check import name_problem

MANIFEST = "_mavscope_dataset.json"
STAGING = "_staging"
FORMAT = "mavscope-dataset"
PART = "part-0.parquet"
COMPRESSION = "zstd"


def dictionary_columns(schema: pa.Schema) -> list[str]:
    """The columns written dictionary-encoded: the text ones (message names, verdicts, enum names, endpoints:
    few distinct values). Numbers and bytes are written plain, which zstd compresses as well or better:
    on the 1M-frame bench capture 19% less CPU to write and 19% smaller files than dictionaries for every
    column (docs/performance.md, "Exporting datasets")."""
    return [f.name for f in schema if pa.types.is_string(f.type) or pa.types.is_large_string(f.type)]


def inside(root: Path, *names: str) -> Path:
    """`root` joined with `names`, each one plain file name (not empty, `.` or `..`, no separator, NUL or
    drive), and the result, symbolic links followed, still inside `root` (DatasetError otherwise). Every
    file name an export makes holds a dialect's or a capture's strings (a message name, a capture's file
    name): checked at the source (mavscope.mavlink.dialect_check), and confined here, where it is used."""
    for name in names:
        if not name or name in (".", "..") or any(c in name for c in "/\\:\0"):
            raise DatasetError(f"{root}: {name!r} cannot name a file there (one plain file name is needed)")
    path = root.joinpath(*names)
    try:
        real, top = path.resolve(), root.resolve()
    except (OSError, RuntimeError) as e:  # a symbolic link loop
        raise DatasetError(f"{path}: cannot be used: {e}") from None
    if not real.is_relative_to(top):
        raise DatasetError(f"{path}: leads outside {root} (a symbolic link); nothing written there")
    return path


def valid_table(name: str) -> bool:
    """Whether `name` can be a table of a dataset: a fixed table or `msg=` and a message name (an
    identifier in upper case, as dialects are held to): a directory of any other name (a glob character
    DuckDB would expand, a name no dialect can give) is no table."""
    if name in FIXED_TABLES:
        return True
    return name.startswith(MESSAGE_PREFIX) and name_problem(name[len(MESSAGE_PREFIX):], upper=True) is None


def partition_dir(root: Path, table: str, capture_id: str) -> Path:
    return inside(root, table, f"{PARTITION}={capture_id}")


def read_manifest(root: Path) -> dict[str, object] | None:
    """The manifest of the dataset at `root`, None when there is none (DatasetError if unreadable)."""
    path = root / MANIFEST
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except OSError as e:
        raise DatasetError(f"{path}: cannot read: {e.strerror or e}") from None
    try:
        doc = json.loads(text)
    except ValueError:
        raise DatasetError(f"{path}: not a mavscope dataset manifest (invalid JSON)") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise DatasetError(f"{path}: not a mavscope dataset manifest")
    return doc


def check_version(root: Path, doc: dict[str, object]) -> None:
    version = doc.get("schema_version")
    if version != SCHEMA_VERSION:
        raise DatasetError(
            f"{root} is a mavscope dataset of schema version {version}; this mavscope ({__version__}) reads and "
            f"writes version {SCHEMA_VERSION} and cannot migrate it: export the captures into a new directory "
            "(docs/dataset.md, Versions)")


def is_dataset(path: str | os.PathLike[str]) -> bool:
    return (Path(path) / MANIFEST).is_file()


def open_dataset(path: str | os.PathLike[str], *, create: bool) -> Path:
    """The dataset directory at `path`, its version checked; with `create`, made when absent or empty
    (DatasetError for a non-empty directory that is not a dataset)."""
    root = Path(path)
    doc = read_manifest(root) if root.is_dir() else None
    if doc is not None:
        check_version(root, doc)
        return root
    if not create:
        raise DatasetError(f"{root}: not a mavscope dataset (no {MANIFEST})")
    if root.exists() and (not root.is_dir() or any(root.iterdir())):
        raise DatasetError(f"{root}: exists and is not a mavscope dataset (no {MANIFEST}); give a new or empty "
                           "directory")
    root.mkdir(parents=True, exist_ok=True)
    manifest = {"format": FORMAT, "schema_version": SCHEMA_VERSION, "created_by": f"mavscope {__version__}",
                "partitioning": "hive", "partition_column": PARTITION, "documentation": "docs/dataset.md"}
    tmp = root / f".{MANIFEST}.{uuid.uuid4().hex}"
    tmp.write_text(json.dumps(manifest, indent=2) + "\n", encoding="utf-8")
    os.replace(tmp, root / MANIFEST)
    return root


def committed_ids(root: Path) -> set[str]:
    """The captures the dataset holds (those whose `captures` partition was written last)."""
    base = root / CAPTURES
    if not base.is_dir():
        return set()
    prefix = f"{PARTITION}="
    return {p.name[len(prefix):] for p in base.iterdir() if p.name.startswith(prefix) and (p / PART).is_file()}


def is_committed(root: Path, capture_id: str) -> bool:
    return (partition_dir(root, CAPTURES, capture_id) / PART).is_file()


def tables(root: Path) -> list[str]:
    """The table directories of the dataset (frames, msg=HEARTBEAT...)."""
    return sorted(p.name for p in root.iterdir() if p.is_dir() and valid_table(p.name))


@dataclass(frozen=True, slots=True)
class CaptureResult:
    """What happened to one capture: exported, skipped (already in the dataset) or failed."""

    path: str
    capture_id: str | None
    status: str  # "exported", "skipped", "duplicate", "failed"
    frames: int = 0
    seconds: float = 0.0
    size: int = 0
    error: str = ""
    problems: int = 0  # problems reading it, as `read` reports them (the captures table's problem_count)
    first_problem: str = ""

    def to_json(self) -> dict[str, object]:
        return {"path": self.path, "capture_id": self.capture_id, "status": self.status, "frames": self.frames,
                "seconds": round(self.seconds, 3), "bytes": self.size, "error": self.error or None,
                "problems": self.problems, "first_problem": self.first_problem or None}


class _Writers:
    """One Parquet file per table of a capture in the staging folder (STAGE/TABLE/part-0.parquet: the
    folder becomes the partition when renamed), opened at the table's first batch; `durable` syncs each
    file to disk before it is renamed into place."""

    def __init__(self, stage: Path, capture_id: str, durable: bool = True) -> None:
        self.stage = stage
        self.capture_id = capture_id
        self.durable = durable
        self.open: dict[str, pq.ParquetWriter] = {}
        self.frames = 0
        self.problems = 0
        self.first_problem = ""

    def write(self, batch: pa.RecordBatch) -> None:
        if not batch.num_rows:
            return
        table = table_of(batch)
        body = batch.drop_columns([PARTITION])  # the directory name holds it (Hive partitioning)
        w = self.open.get(table)
        if w is None:
            d = inside(self.stage, table)
            d.mkdir()
            w = self.open[table] = pq.ParquetWriter(d / PART, body.schema, compression=COMPRESSION,
                                                    use_dictionary=dictionary_columns(body.schema))
        w.write_batch(body)
        if table == "frames":
            self.frames += batch.num_rows
        elif table == CAPTURES:  # (any batch source writes it: the problems travel with the result)
            self.problems = int(batch.column("problem_count")[0].as_py() or 0)
            self.first_problem = batch.column("first_problem")[0].as_py() or ""

    def close(self) -> None:
        for w in self.open.values():
            w.close()
        if not self.durable:
            return
        for table in self.open:
            fd = os.open(self.stage / table / PART, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)


WRITE_BEHIND = 2  # batches made and waiting for the writer thread at most (each up to a row group)


def write_behind(batches: Iterator[pa.RecordBatch], write: Callable[[pa.RecordBatch], None]) -> None:
    """`write` every batch of `batches`, on a thread of its own while the next batches are made: Parquet's
    encoding and compression (pyarrow, without the GIL) overlap the walk and the analyses. At most
    WRITE_BEHIND batches wait. The first error of either side is raised here, after both have stopped."""
    todo: queue.Queue[pa.RecordBatch | None] = queue.Queue(WRITE_BEHIND)
    failed: list[BaseException] = []

    def writer() -> None:
        while (b := todo.get()) is not None:
            if not failed:
                try:
                    write(b)
                except BaseException as e:  # noqa: BLE001 - handed to the caller's thread
                    failed.append(e)

    t = threading.Thread(target=writer, name="mavscope-parquet", daemon=True)
    t.start()
    try:
        for b in batches:
            if failed:
                break
            todo.put(b)
    finally:
        todo.put(None)
        t.join()
        close = getattr(batches, "close", None)
        if close is not None:  # a generator left early: its files and walker closed now
            close()
    if failed:
        raise failed[0]


def remove_capture(root: Path, capture_id: str) -> None:
    """Every partition of `capture_id`, its `captures` partition first (so that it is never committed
    with a table missing), and staging folders an interrupted export of it left."""
    for table in [CAPTURES] + [t for t in tables(root) if t != CAPTURES]:
        d = partition_dir(root, table, capture_id)
        if d.exists():
            shutil.rmtree(d)
    staging = root / STAGING
    if staging.is_dir():
        for d in staging.glob(f"{capture_id}.*"):
            shutil.rmtree(d, ignore_errors=True)


def _commit(root: Path, stage: Path, capture_id: str, names: list[str]) -> bool:
    """Rename the staged partitions into place, `captures` last. False when another export committed
    the same capture meanwhile (its content is the same: ours is dropped)."""
    if is_committed(root, capture_id):
        return False
    for table in sorted(names, key=lambda t: t == CAPTURES):
        target = partition_dir(root, table, capture_id)
        target.parent.mkdir(exist_ok=True)
        if target.exists():  # left by an unfinished export of the same capture
            shutil.rmtree(target)
        os.replace(stage / table, target)
    return True


def export_capture(dataset: str | os.PathLike[str], path: str, options: ExportOptions | None = None, *,
                   replace: bool = False, durable: bool = True, progress: Progress | None = None,
                   warn: Warn | None = None) -> CaptureResult:
    """Export one capture into the dataset at `dataset` (which must exist: `open_dataset`), atomically.

    Skipped when its content is there already, unless `replace` (which removes it, then exports it).
    `durable` syncs every file to disk before the commit (a power loss cannot leave a committed capture
    with a file missing; a process crash cannot either way).
    An unreadable capture or bad options give a "failed" result with the one-line error."""
    from mavscope.errors import MavscopeError

    root = Path(dataset)
    options = options or ExportOptions()
    t0 = time.perf_counter()
    try:
        size = os.path.getsize(path)
    except OSError:
        size = 0
    try:
        cid = options.capture_id or content_id(path)
    except MavscopeError as e:
        return CaptureResult(path, None, "failed", size=size, error=str(e))
    if is_committed(root, cid) and not replace:
        return CaptureResult(path, cid, "skipped", size=size)
    remove_capture(root, cid)
    stage = inside(root, STAGING, f"{cid}.{uuid.uuid4().hex}")
    stage.mkdir(parents=True)
    writers = _Writers(stage, cid, durable)
    try:
        try:
            write_behind(record_batches(path, dc_replace(options, capture_id=cid, tables=None), progress=progress,
                                        warn=warn), writers.write)
        finally:
            writers.close()
        done = _commit(root, stage, cid, list(writers.open))
    except MavscopeError as e:
        return CaptureResult(path, cid, "failed", size=size, error=str(e), seconds=time.perf_counter() - t0)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return CaptureResult(path, cid, "exported" if done else "duplicate", frames=writers.frames,
                         seconds=time.perf_counter() - t0, size=size, problems=writers.problems,
                         first_problem=writers.first_problem)
