"""What the capture-reading subcommands share: their options, turned into `PipelineOptions` once.

Nothing below the command line sees argparse: `pipeline_options(args, env)` is where parsed arguments
become the frozen options every front end hands to `mavscope.pipeline.session`.
"""

from __future__ import annotations

import argparse
import codecs
import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from enum import Enum
from typing import Any, BinaryIO, cast

from mavscope.capture.reader import CaptureReader
from mavscope.cli import Env
from mavscope.errors import UsageError
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.notes import Note, is_capture_damage, problem_line
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import Session, open_session
from mavscope.security.keys import KEYRING_ENV


def add_capture_options(p: argparse.ArgumentParser) -> None:
    """FILE / -r FILE and --dialect."""
    p.add_argument("file", nargs="?", help="capture file: pcap, pcapng, tlog or raw bytes (detected by content)")
    p.add_argument("-r", dest="file_opt", metavar="FILE", help="capture file (tshark spelling)")
    add_dialect_option(p)


def add_dialect_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dialect", action="append", default=[], metavar="XML",
                   help="load another dialect XML (repeatable; dissectors/*.xml load automatically)")


def capture_path(args: argparse.Namespace) -> str:
    path = args.file_opt or args.file
    if not path:
        raise UsageError(f"{args.command}: a capture file is required (mavscope {args.command} FILE)")
    if args.file_opt and args.file:
        raise UsageError(f"{args.command}: give the capture file once (either FILE or -r FILE)")
    return str(path)


def whole_number(minimum: int = 1, unit: str = "") -> Callable[[str], int]:
    """An argparse type: plain ASCII digits (not str.isdigit's '²', not int()'s '+5' or '5_000') making a
    number of at least `minimum`; `unit` names what is counted in the error ("frames")."""
    what = (f"a whole positive number{unit}" if minimum == 1 else f"a whole number{unit} (0 or more)" if minimum == 0
            else f"a whole number{unit} of at least {minimum}")

    def parse(text: str) -> int:
        plain = text.strip()
        if not (plain.isascii() and plain.isdigit()) or int(plain) < minimum:
            raise argparse.ArgumentTypeError(f"{what}, not {text!r}")
        return int(plain)

    return parse


STDOUT = "-"  # an output option's name for standard output, as tshark's `-w -`


class OutputKind(Enum):
    """What an output option writes, which decides what `-` (standard output) does: text is written there;
    bytes (pcap, PNG) are written to its binary buffer when it is not a terminal, else refused; a directory
    is refused (a file literally named `-` is never created: `./-` names one)."""

    TEXT = "text"
    BINARY = "binary"
    DIRECTORY = "directory"


class OutputOption(argparse.Action):
    """An option naming where a command writes its output (`add_output_option`): a store action that knows
    its kind, so the rules of `-` are kept in one place (`check_outputs`) and a test walking the parsers
    finds every output option."""

    def __init__(self, option_strings: Sequence[str], dest: str, kind: OutputKind = OutputKind.TEXT,
                 **kwargs: Any) -> None:
        super().__init__(option_strings, dest, **kwargs)
        self.kind = kind

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        setattr(namespace, self.dest, values)


_STDOUT_HELP = {OutputKind.TEXT: " ('-': standard output)",
                OutputKind.BINARY: " ('-': standard output, when it is not a terminal)",
                OutputKind.DIRECTORY: ""}


def add_output_option(p: argparse.ArgumentParser | argparse._ArgumentGroup, *flags: str, kind: OutputKind,
                      help: str, **kwargs: Any) -> argparse.Action:
    """An option naming an output file or directory (`kind`), its help saying what `-` means; kept in the
    parsed arguments (`args.outputs`: (option, dest, kind) each) for check_outputs."""
    action = p.add_argument(*flags, action=OutputOption, kind=kind, help=help + _STDOUT_HELP[kind], **kwargs)
    known = p.get_default("outputs") or ()
    p.set_defaults(outputs=(*known, (max(action.option_strings, key=len), action.dest, kind)))
    return action


def output_options(parser: argparse.ArgumentParser) -> list[OutputOption]:
    """The output options of a command's parser."""
    return [a for a in parser._actions if isinstance(a, OutputOption)]


def _binary_stdout(env: Env) -> BinaryIO | None:
    """Standard output's binary buffer (None where the stream has none: bytes cannot go there)."""
    buf = getattr(env.stdout, "buffer", None)
    return cast("BinaryIO", buf) if buf is not None and hasattr(buf, "write") else None


def _is_terminal(stream: object) -> bool:
    try:
        return bool(stream.isatty())  # type: ignore[attr-defined]
    except (AttributeError, ValueError):
        return False


def check_outputs(args: argparse.Namespace, env: Env, *, stdout_used: str | None = None) -> Env:
    """The rules of the output options of the command (`add_output_option`) as given, checked
    before the capture is read; the Env the command's report (its text: tables, "written to" lines) is
    written to.

    A file output never names the capture (`not_the_capture`). `-` is standard output, as tshark's
    `-w -`: at most one output goes there; a directory cannot; bytes only to a stream that is not a
    terminal. When an output takes standard output nothing else is written there (tshark prints nothing
    else on it): the report goes to stderr, and an output the user asked for on stdout as well
    (`stdout_used`: "--json", "-V"...) is refused."""
    command = args.command
    to_stdout = []
    for option, dest, kind in getattr(args, "outputs", ()):
        out = getattr(args, dest, None)
        if not out:
            continue
        if out != STDOUT:
            if kind is not OutputKind.DIRECTORY and (getattr(args, "file", None) or getattr(args, "file_opt", None)):
                not_the_capture(option, out, args)
            continue
        if kind is OutputKind.DIRECTORY:
            raise UsageError(f"{command}: {option} -: {option} names a directory, which standard output cannot be "
                             "(./- names a directory called '-')")
        if kind is OutputKind.BINARY:
            if _is_terminal(env.stdout):
                raise UsageError(f"{command}: {option} -: standard output is a terminal; redirect it to a file "
                                 "or a pipe (the output is binary)")
            if _binary_stdout(env) is None:
                raise UsageError(f"{command}: {option} -: standard output takes no bytes here")
        to_stdout.append(option)
    if len(to_stdout) > 1:
        raise UsageError(f"{command}: only one output can go to stdout ({' and '.join(to_stdout)} are both -)")
    if to_stdout and stdout_used:
        raise UsageError(f"{command}: {to_stdout[0]} - writes to standard output, so {stdout_used} cannot "
                         "(give one of them a file)")
    if not to_stdout:
        return env
    return Env(stdout=env.stderr, stderr=env.stderr, environ=env.environ)


def write_output(env: Env, args: argparse.Namespace, option: str, out: str, data: str | bytes) -> None:
    """`data` written to the file `out` named by `option`, or to standard output for `-` (bytes to its
    binary buffer: check_outputs has made sure there is one and that it is not a terminal)."""
    if out == STDOUT:
        if isinstance(data, str):
            env.stdout.write(data)
            env.stdout.flush()
            return
        env.stdout.flush()
        buf = _binary_stdout(env)
        assert buf is not None  # check_outputs refused a stream without one
        buf.write(data)
        buf.flush()
        return
    try:
        if isinstance(data, str):
            with open(out, "w", encoding="utf-8", newline="\n") as fh:
                fh.write(data)
        else:
            with open(out, "wb") as fb:
                fb.write(data)
    except OSError as exc:
        raise UsageError(f"{args.command}: {option} {out}: {exc.strerror or exc}") from None


def binary_stdout(env: Env) -> BinaryIO:
    """Standard output's binary buffer for an output option given as `-` (after check_outputs)."""
    env.stdout.flush()
    buf = _binary_stdout(env)
    if buf is None:
        raise UsageError("standard output takes no bytes here")
    return buf


def not_the_capture(option: str, out: str | None, args: argparse.Namespace) -> None:
    """UsageError when the output file `out` of `option` is the capture being read: a forensics tool
    never writes over its evidence. Checked before the capture is read."""
    if not out or out == "-":
        return
    capture = capture_path(args)
    try:
        same = os.path.exists(out) and os.path.samefile(out, capture)
    except OSError:
        same = False
    if same:
        raise UsageError(f"{args.command}: {option} {out} is the capture being read")


def add_key_options(p: argparse.ArgumentParser) -> None:
    """--key, --cipher, --ecdh-private, --use-leaked-keys, --wifi-key (docs/security.md)."""
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
    g.add_argument("--wifi-key", action="append", default=[], metavar="wpa-pwd:PASSPHRASE:SSID",
                   help="decrypt a WPA2 network's 802.11 frames (CCMP, GCMP) from its 4-way handshakes: "
                        "wpa-pwd:PASSPHRASE:SSID (the SSID after the last ':', %%XX for any byte) or "
                        "wpa-psk:<64 hex>; repeatable")


def add_filter_option(p: argparse.ArgumentParser) -> None:
    """-Y FILTER: keep only the MAVLink frames a display filter matches (docs/filters.md)."""
    p.add_argument("-Y", dest="display_filter", metavar="FILTER",
                   help="display filter, e.g. 'COMMAND_LONG.command == MAV_CMD_NAV_RETURN_TO_LAUNCH' "
                        "(docs/filters.md); applies per MAVLink frame")


def pipeline_options(args: argparse.Namespace, env: Env) -> PipelineOptions:
    """The pipeline options a command's arguments ask for (options a command does not have stay default)."""
    given = vars(args)
    return PipelineOptions(
        dialects=tuple(given.get("dialect") or ()),
        keys=tuple(given.get("key") or ()),
        ciphers=tuple(given.get("cipher") or ()),
        ecdh_private=tuple(given.get("ecdh_private") or ()),
        use_leaked_keys=bool(given.get("use_leaked_keys")),
        wifi_keys=tuple(given.get("wifi_key") or ()),
        keyring=env.environ.get(KEYRING_ENV) or None,
        display_filter=given.get("display_filter") or None,
    )


def plain_utf8(env: Env) -> bool:
    """Whether stdout is not a terminal and encodes text as UTF-8 (the native lines are UTF-8 bytes)."""
    try:
        if env.stdout.isatty():
            return False
    except (AttributeError, ValueError):
        return False
    encoding = getattr(env.stdout, "encoding", None)
    return encoding is None or codecs.lookup(encoding).name == "utf-8"


def console(env: Env):  # type: ignore[no-untyped-def]
    """A rich Console on the command's stdout."""
    from mavscope.output.tables import console as make_console

    return make_console(env.stdout, env.environ)


def write_json(env: Env, doc: object) -> None:
    """One JSON document on the command's stdout."""
    from mavscope.output.tables import write_json as write

    write(env.stdout_bytes, doc)
    env.stdout_bytes.flush()


def warner(env: Env) -> Callable[[str], None]:
    """Where the pipeline's warnings go: one line each on stderr."""
    def warn(message: str) -> None:
        env.say(message)
    return warn


@contextmanager
def capture_session(args: argparse.Namespace, env: Env, dialect: Dialect | None = None) -> Iterator[Session]:
    """The session of the capture named by `args`, with the pipeline its options ask for."""
    with open_session(capture_path(args), pipeline_options(args, env), dialect=dialect,
                      warn=warner(env), environ=env.environ) as session:
        yield session
        walked = session.walked  # the native walker's counts, where it read the capture
        size = walked["size"] if walked else session.reader.size
        if session.frame_count == 0 and (walked["position"] if walked else session.reader.position) >= size:
            env.say(f"no MAVLink frames found in {session.name} ({size} bytes, detected as {session.reader.kind})")


class Problems:
    """Writes what went wrong with the capture to stderr, one line each: problems that belong to no frame
    (anomalies) and damage to the capture file that a frame carries a note of (a cut pcapng must not pass
    in silence). At most LIMIT lines per code, then one line with how many more (a hostile capture could
    otherwise print a line per record); the frames' own notes (JSON, the tree) still hold every one."""

    LIMIT = 20

    def __init__(self, env: Env, name: str) -> None:
        self.env = env
        self.name = name
        self.counts: dict[str, int] = {}

    def _line(self, code: str, where: str, note: Note) -> None:
        n = self.counts.get(code, 0) + 1
        self.counts[code] = n
        if n <= self.LIMIT:
            self.env.say(f"{self.name}: {problem_line(where, note)}")

    def anomaly(self, item: Anomaly) -> None:
        for note in item.notes:
            self._line(note.code, f"record {item.record}", note)

    def frame(self, frame: Frame) -> None:
        for note in frame.notes:
            if is_capture_damage(note):
                self._line(note.code, f"frame {frame.number}", note)

    def item(self, item: Frame | Anomaly) -> None:
        """An anomaly or a frame with notes (`Session.batches` reports each)."""
        if type(item) is Anomaly:
            self.anomaly(item)
        else:
            self.frame(item)

    def close(self) -> None:
        """One line per code whose lines were cut short."""
        for code, n in self.counts.items():
            if n > self.LIMIT:
                self.env.say(f"{self.name}: {n - self.LIMIT} more {code} problems not shown ({n} in all)")
        self.counts.clear()


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
