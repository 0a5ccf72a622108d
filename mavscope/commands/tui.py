"""`mavscope tui FILE`: browse a capture in a terminal UI (packet list, detail tree, hex; docs/tui.md)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from mavscope.cli import ArgParser, Env, ExitStatus
from mavscope.commands import common
from mavscope.errors import UsageError


def add_options(p: argparse.ArgumentParser) -> None:
    common.add_capture_options(p)
    p.add_argument("--live", action="store_true", help="follow mode: show frames as they arrive (with --udp)")
    p.add_argument("--udp", metavar="[HOST:]PORT", help="with --live: the UDP port to listen on, e.g. 14550")
    p.add_argument("--keep", type=int, default=200_000, metavar="N",
                   help="with --live: frames kept in memory; older ones are dropped (default 200000)")
    # every option the pipeline understands, through the same helpers as `read`
    for helper in ("add_filter_option", "add_security_options", "add_key_options"):
        add = getattr(common, helper, None)
        if add is not None:
            add(p)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tui", help="browse a capture in a terminal UI (list, detail tree, hex)",
                       description="Browse the MAVLink frames of a capture: packet list, detail tree and hex "
                                   "pane, display filter bar, statistics, mission, expert findings, keys. "
                                   "Press ? inside for every key.")
    add_options(p)
    p.set_defaults(run=run)


def parse_options(argv: Sequence[str]) -> argparse.Namespace:
    """`mavscope tui` options from an argument list (for create_app callers such as the tests)."""
    p = ArgParser(prog="mavscope tui")
    add_options(p)
    args = p.parse_args(list(argv))
    args.command = "tui"
    return args


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    from mavscope.tui.app import create_app

    if args.live:
        if not args.udp:
            raise UsageError("tui: --live needs --udp [HOST:]PORT")
        if args.file or args.file_opt:
            raise UsageError("tui: give either a capture file or --live --udp PORT, not both")
        if args.keep < 1000:
            raise UsageError("tui: --keep needs at least 1000 frames")
        path = None
    else:
        if args.udp:
            raise UsageError("tui: --udp goes with --live")
        path = common.capture_path(args)
    isatty = getattr(env.stdout, "isatty", None)
    if isatty is None or not isatty():
        raise UsageError("tui: needs a terminal (use `mavscope read` for output to a file or pipe)")
    app = create_app(path, args, env)
    app.run()
    return ExitStatus.OK
