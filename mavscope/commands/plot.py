"""`mavscope plot FILE EXPR [EXPR...]`: fields over time, per interval count, min, max and mean (Wireshark's
I/O graph), in the terminal, or to a PNG or SVG with --out (matplotlib, the `plot` extra)."""

from __future__ import annotations

import argparse
import os

from mavscope.analysis.series import Plotter
from mavscope.cli import Env, ExitStatus
from mavscope.commands.common import (
    STDOUT,
    OutputKind,
    Problems,
    add_dialect_option,
    add_filter_option,
    add_key_options,
    add_output_option,
    binary_stdout,
    capture_session,
    check_outputs,
    console,
    whole_number,
    write_json,
)
from mavscope.errors import UsageError
from mavscope.fields.registry import FieldRegistry
from mavscope.pipeline.dissect import Anomaly


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plot",
                       description="Plot numeric fields of the field registry over capture time: per interval the "
                                   "mean, minimum and maximum (Wireshark's I/O graph). EXPR: MESSAGE.field "
                                   "(GLOBAL_POSITION_INT.relative_alt), a bare field name, MESSAGE.array[i], or a "
                                   "header field (mavlink.seq, signature.skew). -Y keeps the frames a display "
                                   "filter matches.")
    p.add_argument("words", nargs="+", metavar="FILE EXPR", help="the capture file, then one or more fields")
    p.add_argument("-r", dest="file_opt", metavar="FILE", help="capture file (then every word is a field)")
    add_dialect_option(p)
    add_filter_option(p)
    add_key_options(p)
    p.add_argument("--interval", type=float, metavar="SECONDS",
                   help="bucket width (default: chosen from the capture's length, at most 1024 buckets)")
    add_output_option(p, "--out", metavar="FILE.png|FILE.svg", kind=OutputKind.BINARY,
                      help="draw to an image with matplotlib (- writes PNG)")
    p.add_argument("--width", type=whole_number(0), default=0,
                   help="terminal chart width in characters (default 0: the terminal's)")
    p.add_argument("--height", type=whole_number(2), default=12,
                   help="terminal chart height in lines per field (default 12, at least 2)")
    p.add_argument("--json", action="store_true", help="the buckets as one JSON document (docs/analysis.md)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    words = list(args.words)
    if args.file_opt:
        args.file = None
        exprs = words
    else:
        args.file, exprs = words[0], words[1:]
    if not exprs:
        raise UsageError("plot: give at least one field after the capture file, e.g. GLOBAL_POSITION_INT.relative_alt")
    if args.out and args.out != STDOUT and args.out.rsplit(".", 1)[-1].lower() not in ("png", "svg"):
        raise UsageError(f"plot: --out {args.out}: the file name must end in .png or .svg")
    report = check_outputs(args, env, stdout_used="--json" if args.json else None)  # stderr's for --out -
    with capture_session(args, env) as session:
        plotter = Plotter(FieldRegistry(session.dialect), exprs, args.interval)
        flt = session.display_filter
        problems = Problems(env, session.name)
        try:
            for item in session.items:
                if type(item) is Anomaly:
                    problems.anomaly(item)
                    continue
                if item.notes:
                    problems.frame(item)
                if flt is None or flt.matches(item):
                    plotter.add(item)
        finally:
            problems.close()
        path = session.name
    x_label = plotter.x_label or "s"
    if args.out:
        from mavscope.output.plotting import image

        image(plotter.series, x_label, args.out, f"{os.path.basename(path)}" +
              (f" ({args.display_filter})" if args.display_filter else ""),
              file=binary_stdout(env) if args.out == STDOUT else None)
    if args.json:
        write_json(env, {"file": path, "filter": args.display_filter, "x": x_label, "start": plotter.start,
                         "series": [s.to_json() for s in plotter.series],
                         "image": args.out})
        return ExitStatus.OK
    from mavscope.output.console import text
    from mavscope.output.plotting import chart, summary

    con = console(report)
    width = args.width if args.width > 0 else con.width
    for s in plotter.series:
        con.print(text(summary(s, x_label)) if args.out else chart(s, width, max(2, args.height), x_label))
    if args.out:
        con.print(text(f"wrote {args.out}"))
    return ExitStatus.OK
