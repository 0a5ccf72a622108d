"""What the capture-reading subcommands share: options, opening a capture, the frame pipeline.

`capture_session(args, env)` is the one place where a command gets its frames: it loads the dialects,
opens the capture, runs the dissector and then every later stage the options ask for (key material,
display filters). A stage added here serves `read`, `stats`, `mission` and the rest at once.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from mavscope.analysis.filter import DisplayFilter, compile_filter
from mavscope.capture.base import Record
from mavscope.capture.reader import CaptureReader
from mavscope.cli import Env
from mavscope.dissect import Anomaly, Dissector
from mavscope.errors import UsageError
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.frame import Frame
from mavscope.security.keys import build_material
from mavscope.security.stage import SecurityStage


def add_capture_options(p: argparse.ArgumentParser) -> None:
    """FILE / -r FILE and --dialect."""
    p.add_argument("file", nargs="?", help="capture file: pcap, pcapng, tlog or raw bytes (detected by content)")
    p.add_argument("-r", dest="file_opt", metavar="FILE", help="capture file (tshark spelling)")
    p.add_argument("--dialect", action="append", default=[], metavar="XML",
                   help="load another dialect XML (repeatable; dissectors/*.xml load automatically)")


def capture_path(args: argparse.Namespace) -> str:
    path = args.file_opt or args.file
    if not path:
        raise UsageError(f"{args.command}: a capture file is required (mavscope {args.command} FILE)")
    if args.file_opt and args.file:
        raise UsageError(f"{args.command}: give the capture file once (either FILE or -r FILE)")
    return path


@dataclass
class Session:
    """An open capture and the frames it yields after every stage the options asked for."""

    path: str
    reader: CaptureReader
    dialect: Dialect
    items: Iterator[Frame | Anomaly]
    t0: float | None = None  # time of the capture's first record: relative times count from it (as tshark's)


def build_pipeline(
    args: argparse.Namespace, env: Env, dialect: Dialect, records: Iterable[Record],
    security: SecurityStage | None = None,
) -> Iterator[Frame | Anomaly]:
    """Frames and anomalies of `records` after every stage the options ask for.

    Shared by offline commands (through `capture_session`) and live capture, which feeds records as
    they arrive (and passes its own `security` stage, to hand it keys while it runs). Stages are
    added here, in data-path order.
    """
    items: Iterator[Frame | Anomaly] = Dissector(dialect).run(records)
    if security is None:
        security = security_stage(args, env)
    items = security.run(items)  # verdicts the later stages (filters) may test
    display_filter = getattr(args, "display_filter", None)
    if display_filter:  # the last stage: it may test the verdicts of every stage before it
        items = filter_stage(compile_filter(display_filter, dialect), items)
    return items


def add_key_options(p: argparse.ArgumentParser) -> None:
    """--key, --cipher, --ecdh-private, --use-leaked-keys (docs/security.md)."""
    g = p.add_argument_group("key material (docs/security.md)")
    g.add_argument("--key", action="append", default=[], metavar="[NAME=]SPEC",
                   help="signing key: hex:<64 hex>, base64:..., passphrase:TEXT (SHA-256), qgc:TEXT "
                        "(QGroundControl PBKDF2), file:KEYRING.toml; repeatable ($MAVSCOPE_KEYRING: default keyring)")
    g.add_argument("--cipher", action="append", default=[], metavar="METHOD=SCHEME:KEYSPEC[:iv=HEX]",
                   help="payload cipher for incompat method 1..7: xor, aes-128-ctr, aes-gcm (method 7, "
                        "SecureMAV's XOR 0xAB, needs none); repeatable")
    g.add_argument("--ecdh-private", action="append", default=[], metavar="hex:KEY",
                   help="X25519 private key of one side of MAVSCOPE_KEY_EXCHANGE: derive each epoch's keys")
    g.add_argument("--use-leaked-keys", action="store_true",
                   help="verify the frames after a SETUP_SIGNING with the key it leaks")


def security_stage(args: argparse.Namespace, env: Env) -> SecurityStage:
    """The security stage for the key options in `args` (commands without them get the key-free checks)."""
    material = build_material(getattr(args, "key", None) or (), getattr(args, "cipher", None) or (),
                              getattr(args, "ecdh_private", None) or (),
                              use_leaked_keys=bool(getattr(args, "use_leaked_keys", False)),
                              environ=env.environ, warn=lambda m: env.stderr.write(f"mavscope: {m}\n"))
    return SecurityStage(material)


def add_filter_option(p: argparse.ArgumentParser) -> None:
    """-Y FILTER: keep only the MAVLink frames a display filter matches (docs/filters.md)."""
    p.add_argument("-Y", dest="display_filter", metavar="FILTER",
                   help="display filter, e.g. 'COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH' "
                        "(docs/filters.md); applies per MAVLink frame")


def filter_stage(flt: DisplayFilter, items: Iterable[Frame | Anomaly]) -> Iterator[Frame | Anomaly]:
    """The frames `flt` matches; anomalies (which belong to no frame) pass through."""
    matches = flt.matches
    for item in items:
        if type(item) is Anomaly or matches(item):
            yield item


@contextmanager
def capture_session(args: argparse.Namespace, env: Env) -> Iterator[Session]:
    """Open the capture named by `args` and build its frame pipeline."""
    from mavscope.capture.detect import open_capture

    path = capture_path(args)
    dialect = load_dialect(args.dialect)
    with open_capture(path) as first:
        head = next(iter(first), None)
        t0 = head.time if head is not None else None
    with open_capture(path) as reader:
        yield Session(path, reader, dialect, build_pipeline(args, env, dialect, reader), t0)


def report_anomaly(env: Env, path: str, item: Anomaly) -> None:
    """Problems that belong to no frame go to stderr, one line each, with the file offset where known."""
    for note in item.notes:
        where = f"offset {note.offset}: " if note.offset is not None and str(note.offset) not in note.message else ""
        env.stderr.write(f"mavscope: {path}: record {item.record}: {where}{note.message}\n")


def progress(env: Env, reader: CaptureReader) -> tuple[Callable[[], None], Callable[[], None]]:
    """A rich progress bar on stderr for long files when stderr is a terminal; no-ops otherwise."""
    size = getattr(reader, "size", 0) or 0
    if not env.stderr_is_terminal or size < 8 * 1024 * 1024:
        return (lambda: None), (lambda: None)
    from rich.console import Console
    from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn

    bar = Progress("[progress.description]{task.description}", BarColumn(), DownloadColumn(),
                   TimeRemainingColumn(), console=Console(file=env.stderr), transient=True)
    task = bar.add_task("reading", total=size)
    bar.start()

    def update() -> None:
        bar.update(task, completed=getattr(reader, "position", 0))

    return update, bar.stop
