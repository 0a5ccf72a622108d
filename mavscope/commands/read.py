"""`mavscope read FILE`: dissect a capture like `tshark -r` (summary, -V tree, -x hex, JSON)."""

from __future__ import annotations

import argparse
import contextlib
import os
from typing import TYPE_CHECKING, BinaryIO

from mavscope.cli import Env, ExitStatus
from mavscope.commands import tshark_options
from mavscope.commands.common import (
    STDOUT,
    OutputKind,
    Problems,
    add_capture_options,
    add_filter_option,
    add_key_options,
    add_output_option,
    binary_stdout,
    capture_session,
    check_outputs,
    plain_utf8,
    progress,
    whole_number,
)
from mavscope.commands.tshark_options import add_fields_options, add_statistics_option
from mavscope.errors import UsageError
from mavscope.native.core import NATIVE
from mavscope.output.colour import wants_colour
from mavscope.output.timefmt import Clock, check_format
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.session import tapped

if TYPE_CHECKING:
    from mavscope.output.capture_out import FrameWriter, Written
    from mavscope.output.fields_out import FieldsWriter
    from mavscope.pipeline.session import Session


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("read",
                       description="Dissect every MAVLink frame of a capture.")
    add_capture_options(p)
    add_filter_option(p)
    add_key_options(p)
    p.add_argument("-V", dest="verbose", action="store_true", help="print the detail tree of every frame")
    p.add_argument("-x", dest="hex", action="store_true", help="print a hex dump of every frame")
    p.add_argument("-T", dest="format", choices=("text", "json", "jsonl", "fields"), default="text",
                   help="output format (default text; fields: the -e fields, as tshark -T fields prints them)")
    add_fields_options(p)
    p.add_argument("-t", dest="time_format", metavar="FORMAT", default="r",
                   help="the time column of summary lines, as tshark's -t: r (relative, default), a, ad, adoy "
                        "(absolute, local time), u, ud, udoy (UTC), e (epoch), d (since the previous frame), "
                        "dd (since the previous shown frame)")
    p.add_argument("--color", dest="color", default="auto", metavar="WHEN",
                   help="colour summary lines by verdict, as Wireshark's colouring rules: auto (on a terminal, "
                        "unless NO_COLOR is set; default), always, never")
    p.add_argument("-c", dest="count", type=whole_number(1, " of frames"), metavar="N", help="stop after N frames")
    add_output_option(p, "-w", dest="write", metavar="OUT", kind=OutputKind.BINARY,
                      help="write the capture records holding the shown frames (.pcapng, .tlog by the name; pcap "
                           "otherwise and for -; with - nothing else is printed on standard output, as tshark's)")
    p.add_argument("-q", dest="quiet", action="store_true", help="no per-frame output (useful with -w, -z)")
    add_statistics_option(p)
    p.add_argument("-G", dest="glossary", choices=("fields", "values"),
                   help="print a glossary instead of reading a capture, as tshark -G prints it: fields (every "
                        "field's name, type and description) or values (the named values of integer fields)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    if args.glossary:
        return _glossary(args, env)
    # -w - writes the records to standard output and prints no frame there (tshark's -w -); a frame output
    # asked for as well is refused, as tshark refuses "-w - -V": both cannot go to standard output
    asked = "-V" if args.verbose else "-x" if args.hex else f"-T {args.format}" if args.format != "text" else None
    check_outputs(args, env, stdout_used=asked)
    check_format(args.time_format)
    wants_colour(args.color, env.stdout, env.environ)  # (a wrong --color before the capture is read)
    tshark_options.check(args, "read", stdout_records=args.write == STDOUT)
    records_out = binary_stdout(env) if args.write == STDOUT else None
    if records_out is not None:
        args.quiet = True
    with capture_session(args, env) as session:
        if _batch_fields(args):
            _run_fields_batches(args, env, session)
            return ExitStatus.OK
        if _native_eligible(args, env, session):
            _run_native(args, env, session)
            return ExitStatus.OK
        written = _run_python(args, env, session, records_out)
    if written is not None and written.warning:
        env.say(f"warning: -w {args.write}: {written.warning}")
    return ExitStatus.OK


def _run_python(args: argparse.Namespace, env: Env, session: Session, records_out: BinaryIO | None,
                ) -> Written | None:
    """The frames of `session` through the Python pipeline: the printer, -w, -c, -q."""
    from mavscope.output.capture_out import frame_comment, open_output, write_records
    from mavscope.output.printer import FramePrinter

    out_b = env.stdout_bytes
    limit = args.count if args.count is not None else -1
    shown_records: set[int] = set()
    comments: dict[int, list[str]] = {}  # -w OUT.pcapng: each record's frames' verdicts, as packet comments
    shown = 0
    with contextlib.ExitStack() as files:
        t0 = session.t0
        path, name, dialect = session.path, session.name, session.dialect
        frame_writer = _open_writer(args.write, session.reader.kind, records_out) if args.write else None
        out_file = records_out if records_out is not None and frame_writer is None else \
            files.enter_context(open_output(args.write)) if args.write and frame_writer is None else None
        update, stop = progress(env, session.reader)
        zstats = None
        if args.statistics:
            from mavscope.output.zstats import ZStats

            zstats = ZStats(args.statistics, dialect, t0)
        if zstats is not None:  # every frame, as tshark's statistics see every packet whatever -Y shows
            session.items = tapped(session.items, zstats.frame)
        clock = Clock(args.time_format, t0)
        session.record_hooks.append(lambda rec: clock.captured(rec.number, rec.time))  # every record's (-t d)
        printer = _fields_writer(args, env, session, clock) if args.format == "fields" else FramePrinter(
            env.stdout, out_b, dialect, args.format, verbose=args.verbose, hex=args.hex, quiet=args.quiet, t0=t0,
            clock=clock if args.time_format != "r" else None,
            colour=args.format == "text" and wants_colour(args.color, env.stdout, env.environ))
        show = printer.frame
        problems = Problems(env, name)
        try:
            printer.begin()
            for n, item in enumerate(session.shown()):
                if not n & 0x3FFF:
                    update()
                if type(item) is Anomaly:
                    problems.anomaly(item)
                    continue
                frame = item
                if frame.notes:
                    problems.frame(frame)
                shown += 1
                if frame_writer is not None:
                    frame_writer.write(frame)
                elif args.write:
                    shown_records.update(frame.records)
                    comments.setdefault(frame.record, []).append(frame_comment(frame))
                show(frame)
                if shown == limit:
                    break
            printer.end()
            if zstats is not None:
                for _ in session.items:  # (-c stopped early: the statistics still count every frame)
                    pass
                zstats.write(env.stdout)
        finally:
            stop()
            problems.close()
            written = frame_writer.close() if frame_writer is not None else None
        out_b.flush()
        if out_file is not None:
            written = write_records(path, args.write, shown_records, out_file, comments)
    return written


def _glossary(args: argparse.Namespace, env: Env) -> ExitStatus:
    """`read -G fields|values` (no capture read): the loaded dialect's fields or named values."""
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.output.glossary import fields_lines, values_lines

    if args.file or args.file_opt:
        raise UsageError("read: -G prints a glossary and reads no capture: give no FILE")
    lines = fields_lines if args.glossary == "fields" else values_lines
    out = env.stdout
    for line in lines(load_dialect(tuple(args.dialect))):
        out.write(line + "\n")
    return ExitStatus.OK


def _fields_writer(args: argparse.Namespace, env: Env, session: Session, clock: Clock) -> FieldsWriter | _Quiet:
    """The -T fields writer of the -e fields and -E options (nothing printed with -q)."""
    from mavscope.fields.registry import FieldRegistry
    from mavscope.output.fields_out import FieldsWriter, parse_format

    writer = FieldsWriter(env.stdout, FieldRegistry(session.dialect), args.fields,
                          parse_format(args.field_options), clock)
    return _Quiet() if args.quiet else writer


def _batch_fields(args: argparse.Namespace) -> bool:
    """`-T fields` over the session's batches (output.fields_batch), on either engine: every frame shown (no
    display filter), nothing written or counted after (-w, -z), no field that needs every record's time."""
    from mavscope.output.fields_batch import serves

    return (args.format == "fields" and not args.quiet and not args.display_filter and not args.write
            and not args.statistics and serves(args.fields))


def _run_fields_batches(args: argparse.Namespace, env: Env, session: Session) -> None:
    from mavscope.fields.registry import FieldRegistry
    from mavscope.output.fields_batch import BatchFieldsWriter
    from mavscope.output.fields_out import parse_format

    writer = BatchFieldsWriter(env.stdout, FieldRegistry(session.dialect), args.fields,
                               parse_format(args.field_options), Clock(args.time_format, session.t0),
                               native=session.engine == NATIVE)
    problems = Problems(env, session.name)
    update, stop = progress(env, session.reader)
    left = args.count
    try:
        writer.begin()
        for b in session.batches(problems.item):
            update()
            taken = writer.batch(b, left)
            if left is not None:
                left -= taken
                if left <= 0:
                    break
        writer.end()
    finally:
        stop()
        problems.close()


class _Quiet:
    """-q: the frames are read, counted and written with -w, nothing printed."""

    def begin(self) -> None: ...
    def frame(self, _frame: object) -> None: ...
    def end(self) -> None: ...


def _native_eligible(args: argparse.Namespace, env: Env, session: Session) -> bool:
    """The native engine (where the session runs on it) serves plain `read -T jsonl` (no filter, count, -w
    or -q) and the plain summary lines (`read FILE`, `-c N` too; no -V, -x, filter, -w or -q) written to a
    stream that is not a terminal and takes UTF-8; its output is byte-identical to the Python path's
    (docs/native.md)."""
    if (session.engine != NATIVE or args.display_filter or args.write or args.quiet or args.time_format != "r"
            or args.statistics):
        return False
    if args.format == "jsonl":
        return args.count is None
    return (args.format == "text" and not args.verbose and not args.hex and plain_utf8(env)
            and not wants_colour(args.color, env.stdout, env.environ))


def _run_native(args: argparse.Namespace, env: Env, session: Session) -> None:
    """`read -T jsonl` through mavscope.native.walk.write_jsonl, the summary lines through
    mavscope.native.summary.write_summary, over the session's capture, dialect and security stage (the
    session opened them: its errors and warnings came first); the walk's counts go to the session, which
    says when the capture held no frame."""
    out_b = env.stdout_bytes
    where = _Position(os.path.getsize(session.path))
    update, stop = progress(env, where)  # type: ignore[arg-type]  # it reads .size and .position only
    problems = Problems(env, session.name)

    def advance(position: int) -> None:
        where.position = position
        update()

    path, dialect, stage, kind = session.path, session.dialect, session.security, session.reader.kind
    try:
        if args.format == "text":
            from mavscope.native.summary import write_summary

            stats = write_summary(path, dialect, stage, out_b, problems, session.t0, args.count, progress=advance,
                                  kind=kind)
        else:
            from mavscope.native.walk import write_jsonl

            stats = write_jsonl(path, dialect, stage, out_b, problems, progress=advance, kind=kind)
    finally:
        stop()
        problems.close()
    out_b.flush()
    session.walked.update(stats)
    session.frame_count = stats["frames"]


class _Position:
    """What the progress bar reads of a capture walked natively."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.position = 0


def _open_writer(out: str, kind: str, stdout: BinaryIO | None) -> FrameWriter | None:
    """Check `-w OUT` before reading; a FrameWriter for inputs without packets (tlog, raw), else None
    (`stdout`: standard output's bytes, for `-w -`)."""
    from mavscope.output.capture_out import FrameWriter

    if kind in ("tlog", "raw"):
        return FrameWriter(out, stdout)
    if out.lower().endswith(".tlog"):
        raise UsageError("read: -w: a packet capture is written as .pcap or .pcapng, not .tlog")
    return None
