"""`mavscope tui FILE`: browse a capture in a terminal UI (packet list, detail tree, hex; docs/tui.md)."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence

from mavscope.cli import ArgParser, Env, ExitStatus
from mavscope.commands.common import (
    add_capture_options,
    add_filter_option,
    add_key_options,
    capture_path,
    pipeline_options,
)
from mavscope.errors import UsageError
from mavscope.tui.sessions import DEFAULT_KEEP, TuiOptions


def add_options(p: argparse.ArgumentParser) -> None:
    add_capture_options(p)
    p.add_argument("--live", action="store_true", help="follow mode: show frames as they arrive (with --udp)")
    p.add_argument("--udp", metavar="[HOST:]PORT", help="with --live: the UDP port to listen on, e.g. 14550")
    p.add_argument("--keep", type=int, default=DEFAULT_KEEP, metavar="N",
                   help=f"with --live: frames kept in memory; older ones are dropped (default {DEFAULT_KEEP})")
    add_filter_option(p)
    add_key_options(p)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tui",
                       description="Browse the MAVLink frames of a capture: packet list, detail tree and hex "
                                   "pane, display filter bar, statistics, mission, expert findings, keys. "
                                   "Press ? inside for every key.")
    add_options(p)
    p.set_defaults(run=run)


def tui_options(args: argparse.Namespace, env: Env) -> tuple[str | None, TuiOptions]:
    """(capture path or None in follow mode, the options) of parsed `mavscope tui` arguments."""
    options = TuiOptions(pipeline_options(args, env), live=args.live, udp=args.udp, keep=args.keep)
    if args.live:
        if not args.udp:
            raise UsageError("tui: --live needs --udp [HOST:]PORT")
        if args.file or args.file_opt:
            raise UsageError("tui: give either a capture file or --live --udp PORT, not both")
        return None, options
    if args.udp:
        raise UsageError("tui: --udp goes with --live")
    return capture_path(args), options


def parse_options(argv: Sequence[str], environ: Mapping[str, str] | None = None) -> TuiOptions:
    """`mavscope tui` options from an argument list (for create_app callers such as the tests)."""
    p = ArgParser(prog="mavscope tui")
    add_options(p)
    args = p.parse_args(list(argv))
    args.command = "tui"
    return tui_options(args, Env(environ=dict(environ or {})))[1]


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    from mavscope.tui.app import create_app

    path, options = tui_options(args, env)
    if options.live and options.keep < 1000:
        raise UsageError("tui: --keep needs at least 1000 frames")
    isatty = getattr(env.stdout, "isatty", None)
    if isatty is None or not isatty():
        raise UsageError("tui: needs a terminal (use `mavscope read` for output to a file or pipe)")
    create_app(path, options).run()
    return ExitStatus.OK
