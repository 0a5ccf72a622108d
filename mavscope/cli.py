"""The `mavscope` command line (tshark conventions).

`main(argv, env)` takes its streams from an `Env`, so tests run the real entry point with fake
streams and read stdout, stderr and the exit status.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import IO, TYPE_CHECKING

if TYPE_CHECKING:
    from mavscope.export import FrameWriter

from mavscope import __version__
from mavscope.errors import MavscopeError, UsageError


class ExitStatus(IntEnum):
    OK = 0
    FINDINGS = 1  # the command ran and found something the user asked to be told about
    ERROR = 2  # bad usage, unreadable file


@dataclass
class Env:
    """What the command line talks to."""

    stdout: IO[str] = field(default_factory=lambda: sys.stdout)
    stderr: IO[str] = field(default_factory=lambda: sys.stderr)

    @property
    def stdout_bytes(self) -> IO[bytes]:
        buf = getattr(self.stdout, "buffer", None)
        return buf if buf is not None else _TextBytes(self.stdout)

    @property
    def stderr_is_terminal(self) -> bool:
        try:
            return self.stderr.isatty()
        except (AttributeError, ValueError):
            return False


class _TextBytes:
    """A bytes writer over a text stream (for StringIO in tests)."""

    def __init__(self, text: IO[str]) -> None:
        self.text = text

    def write(self, data: bytes) -> int:
        self.text.write(data.decode("utf-8"))
        return len(data)

    def flush(self) -> None:
        self.text.flush()


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="mavscope", description="MAVLink packet analysis and forensics.")
    p.add_argument("--version", action="version", version=f"mavscope {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    r = sub.add_parser("read", help="dissect a capture (pcap, pcapng, tlog, raw) like tshark -r")
    r.add_argument("file", nargs="?", help="capture file (format detected by content)")
    r.add_argument("-r", dest="file_opt", metavar="FILE", help="capture file (tshark spelling)")
    r.add_argument("-V", dest="verbose", action="store_true", help="print the detail tree of every frame")
    r.add_argument("-x", dest="hex", action="store_true", help="print a hex dump of every frame")
    r.add_argument("-T", dest="format", choices=("text", "json", "jsonl"), default="text",
                   help="output format (default text)")
    r.add_argument("-c", dest="count", type=int, metavar="N", help="stop after N frames")
    r.add_argument("-w", dest="write", metavar="OUT", help="write the capture records holding the shown frames")
    r.add_argument("--dialect", action="append", default=[], metavar="XML",
                   help="load another dialect XML (repeatable; dissectors/*.xml load automatically)")
    r.add_argument("-q", dest="quiet", action="store_true", help="no per-frame output (with -w, or for the summary)")
    return p


def _reader_file(args: argparse.Namespace) -> str:
    path = args.file_opt or args.file
    if not path:
        raise UsageError("read: a capture file is required (mavscope read FILE)")
    if args.file_opt and args.file:
        raise UsageError("read: give the capture file once (either FILE or -r FILE)")
    return path


def _progress(env: Env, reader: object) -> tuple[Callable[[], None], Callable[[], None]]:
    """A rich progress bar on stderr for long files when stderr is a terminal; no-ops otherwise."""
    size = getattr(reader, "size", 0) or 0
    if not env.stderr_is_terminal or size < 8 * 1024 * 1024:
        return (lambda: None), (lambda: None)
    from rich.console import Console
    from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn

    progress = Progress("[progress.description]{task.description}", BarColumn(), DownloadColumn(),
                        TimeRemainingColumn(), console=Console(file=env.stderr), transient=True)
    task = progress.add_task("reading", total=size)
    progress.start()

    def update() -> None:
        progress.update(task, completed=getattr(reader, "position", 0))

    def stop() -> None:
        progress.stop()

    return update, stop


def cmd_read(args: argparse.Namespace, env: Env) -> ExitStatus:
    from mavscope.capture.detect import open_capture
    from mavscope.dissect import Anomaly, Dissector
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.output.jsonout import jsonl_bytes
    from mavscope.output.text import detail_text, hexdump, summary_line

    path = _reader_file(args)
    if args.count is not None and args.count < 1:
        raise UsageError("read: -c needs a positive number of frames")
    dialect = load_dialect(args.dialect)
    out_b = env.stdout_bytes
    out = env.stdout
    fmt = args.format
    shown_records: set[int] = set()
    shown = 0
    t0: float | None = None
    anomalies = 0
    limit = args.count if args.count is not None else -1
    with open_capture(path) as reader:
        frame_writer = _open_writer(args.write, path, reader.kind) if args.write else None
        update, stop = _progress(env, reader)
        try:
            if fmt == "json":
                out_b.write(b"[")
            for n, item in enumerate(Dissector(dialect).run(reader)):
                if not n & 0x3FFF:
                    update()
                if type(item) is Anomaly:
                    anomalies += 1
                    for note in item.notes:
                        env.stderr.write(f"mavscope: {path}: record {item.record}: {note.message}\n")
                    continue
                frame = item
                shown += 1
                if frame_writer is not None:
                    frame_writer.write(frame)
                elif args.write:
                    shown_records.update(frame.records)
                if args.quiet:
                    pass
                elif fmt == "jsonl":
                    out_b.write(jsonl_bytes(frame))
                elif fmt == "json":
                    out_b.write((b"\n" if shown == 1 else b",\n") + jsonl_bytes(frame)[:-1])
                else:
                    if t0 is None:
                        t0 = frame.time
                    out.write(summary_line(frame, dialect, t0) + "\n")
                    if args.verbose:
                        out.write(detail_text(frame, dialect) + "\n")
                    if args.hex:
                        out.write(hexdump(frame.raw) + "\n")
                    if args.verbose or args.hex:
                        out.write("\n")
                if shown == limit:
                    break
            if fmt == "json":
                out_b.write(b"\n]\n" if shown else b"]\n")
        finally:
            stop()
            if frame_writer is not None:
                frame_writer.close()
    out_b.flush()
    if args.write and frame_writer is None:
        from mavscope.export import write_records

        write_records(path, args.write, shown_records)
    return ExitStatus.OK


def _open_writer(out: str, source: str, kind: str) -> FrameWriter | None:
    """Check `-w OUT` before reading; a FrameWriter for inputs without packets (tlog, raw), else None."""
    from mavscope.export import FrameWriter

    if os.path.exists(out) and os.path.samefile(out, source):
        raise UsageError(f"-w: {out} is the capture being read")
    if kind in ("tlog", "raw"):
        return FrameWriter(out)
    if out.lower().endswith(".tlog"):
        raise UsageError("-w: a packet capture is written as .pcap or .pcapng, not .tlog")
    return None


COMMANDS: dict[str, Callable[[argparse.Namespace, Env], ExitStatus]] = {"read": cmd_read}


def main(argv: Sequence[str] | None = None, env: Env | None = None) -> int:
    """Entry point of the `mavscope` console script."""
    env = env or Env()
    parser = build_parser()
    try:
        args = parser.parse_args(list(argv) if argv is not None else None)
        if args.command is None:
            parser.print_help(env.stdout)
            return ExitStatus.ERROR
        return int(COMMANDS[args.command](args, env))
    except MavscopeError as exc:
        env.stderr.write(f"mavscope: {exc}\n")
        return ExitStatus.ERROR
    except BrokenPipeError:
        # `mavscope read x | head`: the reader went away; not an error worth a traceback.
        try:
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the interpreter's flush at exit
        except OSError:
            pass
        return ExitStatus.OK
    except KeyboardInterrupt:
        return 130

