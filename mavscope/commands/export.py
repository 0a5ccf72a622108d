"""`mavscope export FILES_OR_DIRS... --parquet DIR`: captures into one Parquet dataset (docs/dataset.md);
`-T csv -o DIR`: mavlogdump-style CSV per message type."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from mavscope.cli import Env, ExitStatus
from mavscope.commands.common import (
    OutputKind,
    add_dialect_option,
    add_key_options,
    add_output_option,
    check_outputs,
    pipeline_options,
    warner,
    whole_number,
    write_json,
)
from mavscope.errors import UsageError

if TYPE_CHECKING:
    from mavscope.export.dataset import CaptureResult
    from mavscope.export.source import ExportOptions

PROGRESS_BYTES = 8 * 1024 * 1024  # a progress bar for inputs at least this large, on a terminal
NAMED_PASSED_OVER = 5  # files passed over in directories, named one by one up to this many


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export",
                       description="Export every capture named (directories are walked) into one dataset: a "
                                   "frames table, a table per message type, findings, anomalies and captures, "
                                   "Parquet partitioned by capture (docs/dataset.md). Captures already in the "
                                   "dataset (same content) are skipped. Exit status 2 when a capture could "
                                   "not be read.")
    p.add_argument("paths", nargs="+", metavar="FILE_OR_DIR", help="captures, or directories holding them")
    add_output_option(p, "--parquet", metavar="DIR", kind=OutputKind.DIRECTORY,
                      help="the dataset directory (created; added to when it exists)")
    p.add_argument("-T", dest="format", choices=("parquet", "csv"), default="parquet",
                   help="parquet (default) or csv (mavlogdump-style, one file per message type and capture)")
    add_output_option(p, "-o", dest="out", metavar="DIR", kind=OutputKind.DIRECTORY,
                      help="output directory (the dataset with -T parquet)")
    p.add_argument("-j", dest="jobs", type=whole_number(1), default=1, metavar="N",
                   help="captures exported at once, in N worker processes (default 1)")
    p.add_argument("--engine", choices=("local", "dask"), default="local",
                   help="local (default) or dask: tasks on a Dask cluster (--scheduler; else a local cluster of "
                        "-j workers)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--replace", action="store_true", help="export captures again that the dataset holds already")
    p.add_argument("--no-fsync", dest="durable", action="store_false",
                   help="do not sync each file to disk before its capture is committed (faster on slow disks; "
                        "a power loss may then lose files of a committed capture, a process crash cannot)")
    p.add_argument("--json", action="store_true", help="print the result per capture as JSON")
    p.add_argument("--unsafe-csv", dest="guard", action="store_false",
                   help="with -T csv: write text that begins with = + - @ as it is (by default it gets a leading ' "
                        "so that a spreadsheet does not run a sender's text as a formula)")
    add_dialect_option(p)
    add_key_options(p)
    p.set_defaults(run=run)


def needs_fleet(*modules: str) -> None:
    """UsageError unless `modules` of the fleet extra (pyarrow, numpy, duckdb, dask) import."""
    import importlib

    missing = []
    for m in modules:
        try:
            importlib.import_module(m)
        except ImportError:
            missing.append(m)
    if missing:
        raise UsageError(f"this command needs {', '.join(missing)}: pip install 'mavscope[fleet]'")


@contextmanager
def bar(env: Env, total: int, what: str) -> Iterator[Callable[[int], None]]:
    """A progress bar over `total` bytes on stderr (a terminal only, and long runs only)."""
    if not env.stderr_is_terminal or total < PROGRESS_BYTES:
        yield lambda _done: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn

    progress = Progress("[progress.description]{task.description}", BarColumn(), DownloadColumn(),
                        TimeRemainingColumn(), console=Console(file=env.stderr), transient=True)
    task = progress.add_task(what, total=total)
    progress.start()
    try:
        yield lambda done: progress.update(task, completed=done)
    finally:
        progress.stop()


def gather(env: Env, paths: list[str], dialects: tuple[str, ...]) -> list[str]:
    """The captures among `paths` (UsageError when a path does not exist); files passed over in directories
    are counted on stderr."""
    from mavscope.export.inputs import MAX_FILES, find_captures
    from mavscope.mavlink.dialect import load_dialect

    found = find_captures(paths, load_dialect(dialects))  # (batch needs no pyarrow: not export.source's cache)
    if found.missing:
        raise UsageError(f"no such file or directory: {found.missing[0]}")
    passed = found.passed_over
    if passed:
        which = (": " + ", ".join(passed) if len(passed) <= NAMED_PASSED_OVER else f" (e.g. {passed[0]})")
        env.say(f"{len(passed)} file(s) in the directories are not captures and were passed over{which}")
    if found.stopped:
        env.say(f"stopped looking in the directories after {MAX_FILES:,} files: the files after those are not "
                "read")
    return found.captures


class Reporter:
    """Says on stderr what `read` would have said of each capture exported: its error, that reading it
    had problems (how many, and the first as `read` writes it: the dataset's `anomalies` table and frame
    notes hold them all) or that it held no MAVLink frame. One line per capture, for at most SHOWN
    captures with problems, then one line for the rest (`close`): a directory of damaged captures must
    not flood the terminal, nor pass in silence."""

    SHOWN = 10

    def __init__(self, env: Env, errors: bool = True) -> None:
        self.env = env
        self.errors = errors
        self.damaged = 0

    def __call__(self, r: CaptureResult) -> None:
        if r.status == "failed" and self.errors:
            self.env.say(str(r.error))
        if r.status != "exported":
            return
        said = [f"{r.problems} problem(s) reading it, the first: {r.first_problem}"] if r.problems else []
        if not r.frames:
            said.append("no MAVLink frames found")
        if said:
            self.damaged += 1
            if self.damaged <= self.SHOWN:
                self.env.say(f"{r.path}: {'; '.join(said)}")

    def close(self) -> None:
        if self.damaged > self.SHOWN:
            self.env.say(f"{self.damaged - self.SHOWN} more capture(s) with problems or without frames not shown "
                         f"({self.damaged} in all; `mavscope read FILE` lists them)")


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    check_outputs(args, env)  # (directories: never -)
    needs_fleet("pyarrow", "numpy")
    out = args.out or args.parquet
    if args.parquet and args.out and args.parquet != args.out:
        raise UsageError("export: give the output directory once (--parquet DIR or -o DIR)")
    if args.parquet and args.format == "csv":
        raise UsageError("export: --parquet writes Parquet; with -T csv give -o DIR")
    if not out:
        raise UsageError("export: no output: --parquet DIR (or -T csv -o DIR)")
    if args.scheduler and args.engine != "dask":
        raise UsageError("export: --scheduler needs --engine dask")
    if args.engine == "dask" and args.format == "csv":
        raise UsageError("export: -T csv runs locally (--engine dask writes Parquet)")
    from mavscope.export.source import ExportOptions, source_name

    # the native batch source where the extension is built, unless MAVSCOPE_PURE=1 (docs/dataset.md)
    options = ExportOptions(pipeline=pipeline_options(args, env), source=source_name("auto", env.environ))
    captures = gather(env, args.paths, options.pipeline.dialects)
    if args.format == "csv":
        return _csv(args, env, captures, Path(out), options)
    return _parquet(args, env, captures, out, options)


def _parquet(args: argparse.Namespace, env: Env, captures: list[str], out: str, options: ExportOptions) -> ExitStatus:
    import os

    from mavscope.export.run import export_local

    report = Reporter(env)
    total = sum(os.path.getsize(p) for p in captures if os.path.isfile(p))
    if args.engine == "dask":
        from mavscope.export.distributed import export_dask

        results = export_dask(out, captures, options, scheduler=args.scheduler, workers=args.jobs,
                              replace=args.replace, durable=args.durable, on_result=report)
    else:
        with bar(env, total, "exporting") as update:
            results = export_local(out, captures, options, jobs=args.jobs, replace=args.replace,
                                   durable=args.durable, on_result=report, on_bytes=update, warn=warner(env))
    report.close()
    failed = [r for r in results if r.status == "failed"]
    if args.json:
        write_json(env, {"dataset": out, "captures": [r.to_json() for r in results],
                         "exported": sum(r.status == "exported" for r in results),
                         "skipped": sum(r.status in ("skipped", "duplicate") for r in results),
                         "failed": len(failed), "frames": sum(r.frames for r in results)})
    else:
        done = [r for r in results if r.status == "exported"]
        skipped = sum(r.status in ("skipped", "duplicate") for r in results)
        seconds = sum(r.seconds for r in done)
        env.stdout.write(f"exported {len(done)} capture(s), {sum(r.frames for r in done):,} frames, to {out}"
                         + (f" ({seconds:.1f} s of work)" if done else "")
                         + (f"; {skipped} already there or repeated" if skipped else "")
                         + (f"; {report.damaged} with problems or no frames (stderr)" if report.damaged else "")
                         + (f"; {len(failed)} failed" if failed else "") + "\n")
    return ExitStatus.ERROR if failed else ExitStatus.OK


def _csv(args: argparse.Namespace, env: Env, captures: list[str], out: Path, options: ExportOptions) -> ExitStatus:
    from mavscope.errors import MavscopeError
    from mavscope.export.csvout import csv_folder, guarded_note, write_capture_csv
    from mavscope.export.dataset import CaptureResult

    taken: set[str] = set()
    failed = 0
    written: list[tuple[str, Path, dict[str, int]]] = []
    guarded = 0
    report = Reporter(env)
    for path in captures:
        folder = csv_folder(out, path, taken)
        try:
            got = write_capture_csv(path, folder, options, warn=warner(env), guard=args.guard)
        except MavscopeError as e:
            env.say(str(e))
            failed += 1
            continue
        report(CaptureResult(path, None, "exported", frames=got.frames, problems=got.problems,
                             first_problem=got.first_problem))
        written.append((path, folder, got.counts))
        guarded += got.guarded
    report.close()
    if guarded:
        env.say(guarded_note("export", guarded), prefix="")
    if args.json:
        write_json(env, {"out": str(out), "failed": failed, "captures": [
            {"path": p, "folder": str(f), "messages": c} for p, f, c in written], "guarded_cells": guarded})
    else:
        files = sum(len(c) for _, _, c in written)
        env.stdout.write(f"wrote {files} CSV file(s) for {len(written)} capture(s) under {out}"
                         + (f"; {report.damaged} with problems or no frames (stderr)" if report.damaged else "")
                         + (f"; {failed} failed" if failed else "") + "\n")
    return ExitStatus.ERROR if failed else ExitStatus.OK
