"""The `mavscope` command line (tshark conventions).

`main(argv, env)` takes its streams from an `Env`, so tests run the real entry point with fake
streams and read stdout, stderr and the exit status. Each subcommand lives in its own module under
`mavscope/commands/` and registers itself through `register(subparsers)`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import IO

from mavscope import __version__
from mavscope.errors import MavscopeError, UsageError

# Subcommand modules, in the order `mavscope --help` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "read", "live", "stats", "mission", "command_log", "timeline", "objects", "params", "events", "track", "plot",
    "tui", "verify", "audit",
)


class ExitStatus(IntEnum):
    OK = 0
    FINDINGS = 1  # the command ran and found something the user asked to be told about
    ERROR = 2  # bad usage, unreadable file
    INTERRUPTED = 130


@dataclass
class Env:
    """What the command line talks to."""

    stdout: IO[str] = field(default_factory=lambda: sys.stdout)
    stderr: IO[str] = field(default_factory=lambda: sys.stderr)
    environ: dict[str, str] = field(default_factory=lambda: dict(os.environ))

    @property
    def stdout_bytes(self) -> IO[bytes]:
        buf = getattr(self.stdout, "buffer", None)
        return buf if buf is not None else _TextBytes(self.stdout)  # type: ignore[return-value]

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


class ArgParser(argparse.ArgumentParser):
    """argparse that raises UsageError instead of exiting, so main() reports it in one line."""

    def error(self, message: str) -> None:  # type: ignore[override]
        prog = self.prog.removeprefix("mavscope").strip()
        raise UsageError(f"{prog}: {message}" if prog else message)


def build_parser() -> argparse.ArgumentParser:
    p = ArgParser(prog="mavscope", description="MAVLink packet analysis and forensics.")
    p.add_argument("--version", action="version", version=f"mavscope {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=ArgParser)
    for name in COMMAND_MODULES:
        importlib.import_module(f"mavscope.commands.{name}").register(sub)
    return p


def main(argv: Sequence[str] | None = None, env: Env | None = None) -> int:
    """Entry point of the `mavscope` console script."""
    env = env or Env()
    parser = build_parser()
    try:
        args = parser.parse_args(list(argv) if argv is not None else None)
        if args.command is None:
            parser.print_help(env.stdout)
            return ExitStatus.ERROR
        return int(args.run(args, env))
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
        return ExitStatus.INTERRUPTED
