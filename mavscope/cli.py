"""The `mavscope` command line (tshark conventions).

`main(argv, env)` takes its streams from an `Env`, so tests run the real entry point with fake
streams and read stdout, stderr and the exit status. Each subcommand lives in its own module under
`mavscope/commands/` and registers itself through `register(subparsers)`.

Only the module of the command being run is imported (its register() builds its parser): the others,
and every command for `mavscope --help`, are listed from COMMANDS alone, so start-up does not pay for
the imports of nine commands (pipeline, filters, security, rich tables) to run one.
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
from mavscope.visible import visible

# Subcommands, in the order `mavscope --help` lists them: name -> (module in mavscope/commands/, one-line
# help). The help is given here, once: the module's register() leaves it out (_Commands adds it).
COMMANDS: dict[str, tuple[str, str]] = {
    "read": ("read", "dissect a capture (pcap, pcapng, tlog, raw) like tshark -r"),
    "live": ("live", "dissect MAVLink live from a UDP port (optionally relaying) or a network interface"),
    "stats": ("stats", "message rates, loss per link, conversations, expert findings"),
    "mission": ("mission", "rebuild mission, fence and rally transfers; export a QGroundControl .plan"),
    "commands": ("command_log", "commands sent (COMMAND_LONG/INT) with their ACK, latency and retries"),
    "timeline": ("timeline", "clocks per system: capture time vs signatures, SYSTEM_TIME, TIMESYNC, PING"),
    "objects": ("objects", "rebuild files (MAVLink FTP), logs and images moved over the link"),
    "params": ("params", "parameters: timeline of sets and changes, final values, .param/.params export"),
    "events": ("events", "the flight's story: arming, modes, mission, texts, failsafes, commands..."),
    "track": ("track", "vehicle tracks with times, mission and fence, as GeoJSON, KML or GPX"),
    "plot": ("plot", "fields over time (avg/min/max per interval) in the terminal, PNG or SVG"),
    "report": ("report", "one self-contained HTML incident report (and JSON) of captures, with chain of custody"),
    "tui": ("tui", "browse a capture in a terminal UI (list, detail tree, hex)"),
    "verify": ("verify", "verify the signatures of a capture; exit 1 on invalid, replayed or injected frames"),
    "audit": ("audit", "security audit: key leaks, replays, forgeries, weak passphrases, fixed keystreams"),
    "rules": ("rules", "detection rules: list the shipped pack, check a rule file (docs/rules.md)"),
    "export": ("export", "captures into one Parquet dataset (DuckDB, Spark, Polars, pandas) or CSV"),
    "sql": ("sql", "SQL (DuckDB) over export datasets or captures"),
    "batch": ("batch", "run verify, audit or stats over many captures in parallel"),
}
COMMAND_MODULES: tuple[str, ...] = tuple(module for module, _ in COMMANDS.values())
# Commands that run another command: what follows `--` is theirs, untouched (`batch DIR -- verify --key K`).
PASSTHROUGH: frozenset[str] = frozenset({"batch"})


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

    def say(self, line: str, prefix: str = "mavscope: ") -> None:
        """One line on stderr, every character a capture or a file name could bring in escaped
        (`visible`): a file name with a line break cannot write a line that looks like one of ours, nor
        an escape sequence reach the terminal."""
        self.stderr.write(prefix + visible(line) + "\n")

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


class _Commands(argparse._SubParsersAction):
    """The subcommands: each parser gets its one-line help from COMMANDS."""

    def add_parser(self, name: str, **kwargs: object) -> argparse.ArgumentParser:
        kwargs.setdefault("help", COMMANDS[name][1])
        return super().add_parser(name, **kwargs)  # type: ignore[arg-type]


class _Version(argparse.Action):
    """--version: the version and the engine `read -T jsonl` and `read` run (mavscope.native, imported only here)."""

    def __init__(self, option_strings: Sequence[str], dest: str, environ: dict[str, str] | None = None,
                 **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs=0, help="show the version and the engine, and exit")
        self.environ = environ

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        from mavscope.native.core import engine

        sys.stdout.write(f"mavscope {__version__} (engine: {engine(self.environ)})\n")  # as argparse's version
        parser.exit()


def command_of(argv: Sequence[str]) -> str | None:
    """The subcommand `argv` runs: its first argument that is not an option, if it names one."""
    for arg in argv:
        if not arg.startswith("-"):
            return arg if arg in COMMANDS else None
    return None


def build_parser(environ: dict[str, str] | None = None, argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The command line's parser. With `argv`, only the parser of the command it runs is built (its module
    imported); the others are listed with their help only. Without, every command's parser is built."""
    p = ArgParser(prog="mavscope", description="MAVLink packet analysis and forensics.")
    p.add_argument("--version", action=_Version, environ=environ)
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=ArgParser, action=_Commands)
    wanted = command_of(argv) if argv is not None else None
    for name, (module, _) in COMMANDS.items():
        if argv is None or name == wanted:
            importlib.import_module(f"mavscope.commands.{module}").register(sub)
        else:
            sub.add_parser(name)  # listed by --help; never parsed (argv runs another command)
    return p


def main(argv: Sequence[str] | None = None, env: Env | None = None) -> int:
    """Entry point of the `mavscope` console script."""
    env = env or Env()
    words = list(argv) if argv is not None else sys.argv[1:]
    rest: list[str] | None = None
    if words and words[0] in PASSTHROUGH and "--" in words:
        cut = words.index("--")
        words, rest = words[:cut], words[cut + 1 :]
    parser = build_parser(env.environ, words)
    try:
        args = parser.parse_args(words)
        if rest is not None:
            args.passthrough = rest
        if args.command is None:
            parser.print_help(env.stdout)
            return ExitStatus.ERROR
        from mavscope.mavlink.dialect import warnings_to  # a dialect's redefinitions: one line each on stderr

        with warnings_to(env.say):
            return int(args.run(args, env))
    except MavscopeError as exc:
        from mavscope.security.redact import redact  # what was typed as key material is never echoed

        typed = [*words, *(rest or [])]
        first, *more = (redact(line, typed) for line in exc.lines())
        env.say(first)
        for line in more:
            env.say(line, prefix="")
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
