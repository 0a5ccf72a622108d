"""`mavscope live`: dissect MAVLink as it arrives on a UDP port (optionally relaying) or an interface.

The records a live source yields go through the same pipeline as a capture file's
(`pipeline.session.build_pipeline`: dissector, security verdicts, display filter) and the same per-frame output as
`read` (`FramePrinter`). Output is flushed whenever mavscope has caught up with the link, so
`mavscope live ... -T jsonl | jq` sees each line as soon as it is decoded. SIGINT and SIGTERM stop
cleanly: the receiver stops, what it already received is decoded, the pcap is flushed and closed, and a
one-line summary goes to stderr (exit status 0).
"""

from __future__ import annotations

import argparse
import io
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import TYPE_CHECKING

from mavscope.capture.base import Record
from mavscope.cli import Env, ExitStatus
from mavscope.commands import tshark_options
from mavscope.commands.common import (
    STDOUT,
    OutputKind,
    Problems,
    add_dialect_option,
    add_filter_option,
    add_key_options,
    add_output_option,
    binary_stdout,
    check_outputs,
    pipeline_options,
    plain_utf8,
    warner,
    whole_number,
)
from mavscope.commands.tshark_options import add_fields_options, add_statistics_option
from mavscope.errors import MavscopeError, UsageError
from mavscope.live.sink import LivePcapWriter
from mavscope.live.source import DEFAULT_QUEUE_ITEMS, LiveSource
from mavscope.live.stop import Stopper
from mavscope.live.udp import BatchReceiver, UdpSource, parse_endpoint
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.frame import Frame
from mavscope.output.colour import wants_colour
from mavscope.output.printer import FramePrinter
from mavscope.output.timefmt import Clock, check_format
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.session import build_pipeline

if TYPE_CHECKING:
    from mavscope.output.fields_out import FieldsWriter


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "live",
        description="Capture and dissect MAVLink as it arrives. Stop with Ctrl-C (or -c / --duration); "
                    "a summary of frames, bytes and drops goes to stderr. See docs/live.md.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--udp", metavar="[HOST:]PORT",
                     help="bind this UDP port (host 0.0.0.0 unless given; [::]:PORT for IPv6)")
    src.add_argument("--sniff", metavar="IFACE",
                     help="capture passively on a network interface (root or CAP_NET_RAW)")
    p.add_argument("--bpf", metavar="EXPR", help="with --sniff: a capture filter, e.g. 'udp port 14550'")
    p.add_argument("--forward", metavar="HOST:PORT",
                   help="with --udp: relay datagrams to HOST:PORT and its replies back to the last sender")
    add_dialect_option(p)
    add_filter_option(p)
    add_key_options(p)
    p.add_argument("-V", dest="verbose", action="store_true", help="print the detail tree of every frame")
    p.add_argument("-x", dest="hex", action="store_true", help="print a hex dump of every frame")
    p.add_argument("-T", dest="format", choices=("text", "jsonl", "fields"), default="text",
                   help="output format (default text; fields: the -e fields, as read -T fields)")
    add_fields_options(p)
    add_statistics_option(p)
    p.add_argument("-q", dest="quiet", action="store_true", help="no per-frame output (useful with -w)")
    p.add_argument("-t", dest="time_format", metavar="FORMAT", default="r",
                   help="the time column of summary lines, as tshark's -t (read -t): r, a, ad, adoy, u, ud, udoy, "
                        "e, d, dd")
    p.add_argument("--color", dest="color", default="auto", metavar="WHEN",
                   help="colour summary lines by verdict (read --color): auto, always, never")
    p.add_argument("-c", dest="count", type=whole_number(1, " of frames"), metavar="N", help="stop after N frames")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    add_output_option(p, "-w", dest="write", metavar="OUT.pcap", kind=OutputKind.BINARY,
                      help="write every packet received to a pcap as it goes (flushed at least every second; with "
                           "- no frame is printed on standard output, as tshark's -w -)")
    p.add_argument("--ring", type=float, metavar="N",
                   help="with -w: keep only the last N MB (OUT and OUT.1 alternate)")
    p.add_argument("--rcvbuf", type=float, default=32, metavar="MB",
                   help="socket receive buffer to ask for (default 32 MB; the granted size is reported)")
    p.add_argument("--queue", type=int, default=DEFAULT_QUEUE_ITEMS, metavar="N",
                   help="datagrams waiting for the decoder before new ones are dropped "
                        f"(default {DEFAULT_QUEUE_ITEMS})")
    p.set_defaults(run=run)


def _check(args: argparse.Namespace) -> None:
    if args.duration is not None and args.duration <= 0:
        raise UsageError("live: --duration needs a positive number of seconds")
    if args.bpf and not args.sniff:
        raise UsageError("live: --bpf goes with --sniff (a UDP port needs no capture filter)")
    if args.forward and not args.udp:
        raise UsageError("live: --forward goes with --udp (the port to relay from)")
    if args.ring is not None and not args.write:
        raise UsageError("live: --ring goes with -w OUT.pcap")
    if args.ring is not None and args.write == STDOUT:
        raise UsageError("live: --ring keeps files on disk: it cannot go with -w -")
    if args.write and args.write != STDOUT and not args.write.lower().endswith((".pcap", ".cap")):
        raise UsageError("live: -w writes a classic pcap: name it OUT.pcap")
    if args.rcvbuf <= 0 or args.queue < 1:
        raise UsageError("live: --rcvbuf and --queue need positive values")


def make_source(args: argparse.Namespace, env: Env) -> LiveSource:
    """The live source the options name (not opened yet)."""
    rcvbuf = int(args.rcvbuf * (1 << 20))
    if args.sniff:
        from mavscope.live.sniff import SniffSource

        return SniffSource(args.sniff, args.bpf, rcvbuf=rcvbuf, max_items=args.queue)
    listen = parse_endpoint(args.udp, what="--udp")
    forward = parse_endpoint(args.forward, what="--forward", default_host=None) if args.forward else None
    if forward is not None and forward.port == 0:
        raise UsageError("--forward: port 0 is not a destination")
    return UdpSource(listen, forward, rcvbuf=rcvbuf, max_items=args.queue, receiver=_receiver(env))


def _receiver(env: Env) -> Callable[[bytes, int], BatchReceiver] | None:
    """The native batch receiver when the native engine runs (MAVSCOPE_PURE unset, extension built)."""
    from mavscope.native.core import engine

    if engine(env.environ) != "native":
        return None
    from mavscope.native.live import receiver_factory

    return receiver_factory()  # type: ignore[return-value]


def _native_lines(args: argparse.Namespace, env: Env, source: LiveSource) -> bool:
    """Whether the native walker writes the lines: a batched source and plain JSON Lines or summary lines
    (no filter, -V or -x; summary lines to a stream that is not a terminal and takes UTF-8), as for `read`,
    or -q (lines made and dropped: the frames are counted, problems reported) (mavscope.native.live)."""
    if not isinstance(source, UdpSource) or not source.batched:
        return False
    if (args.display_filter or args.verbose or args.hex or args.time_format != "r" or args.format == "fields"
            or args.statistics):
        return False
    if args.format != "jsonl" and not args.quiet and (not plain_utf8(env)
                                                      or wants_colour(args.color, env.stdout, env.environ)):
        return False
    from mavscope.native.core import engine

    return engine(env.environ) == "native"


class _Discard(io.RawIOBase):
    """Where `-q` sends the lines (the walk still counts the frames and reports the problems)."""

    def writable(self) -> bool:
        return True

    def write(self, b: object) -> int:
        return len(b)  # type: ignore[arg-type]


def _write_native(args: argparse.Namespace, env: Env, source: LiveSource, dialect: Dialect, stopper: Stopper,
                  writer: LivePcapWriter | None, problems: Problems, printer: FramePrinter) -> int:
    """The lines of the live capture through mavscope.native.live; returns the frames written."""
    from mavscope.native.live import write_live
    from mavscope.output.jsonout import jsonl_bytes
    from mavscope.output.text import summary_line
    from mavscope.pipeline.session import make_security_stage

    stage = make_security_stage(pipeline_options(args, env), warner(env))

    def text(frame: Frame) -> bytes:
        return (summary_line(frame, dialect, printer.t0) + "\n").encode("utf-8")

    def on_t0(t0: float) -> None:
        printer.t0 = t0

    return write_live(source, dialect, stage, _Discard() if args.quiet else env.stdout_bytes, problems,
                      jsonl_bytes if args.format == "jsonl" else text, summary=args.format == "text",
                      count=args.count, stopper=stopper, writer=writer, on_t0=on_t0,
                      idle=writer.tick if writer is not None else None)


def describe(source: LiveSource) -> str:
    if isinstance(source, UdpSource):
        text = f"listening on udp {source.bound}"
        if source.forward is not None:
            text += f", relaying to {source.forward} from {source.up_local[0]}:{source.up_local[1]}"
    else:
        text = f"sniffing on {getattr(source, 'iface', '?')}"
        if getattr(source, "bpf", None):
            text += f" (filter {source.bpf!r})"  # type: ignore[attr-defined]
    return text + f" (receive buffer {getattr(source, 'rcvbuf', 0)} bytes granted)"


def summary(source: LiveSource, frames: int, undecoded: int = 0) -> str:
    st = source.stats()
    kernel = "unknown" if st.kernel_drops is None else str(st.kernel_drops)
    late = f"; {undecoded} received after the stop written but not decoded" if undecoded else ""
    return (f"mavscope: live: {frames} frames, {st.bytes} bytes, {st.dropped} dropped "
            f"({st.queue_drops} queue, {kernel} kernel){late}")


def run(args: argparse.Namespace, env: Env) -> ExitStatus:
    _check(args)
    # -w -: the packets on standard output and no frame printed there (tshark's -w -); a frame output asked
    # for as well is refused, as for `read`
    asked = "-V" if args.verbose else "-x" if args.hex else f"-T {args.format}" if args.format != "text" else None
    check_outputs(args, env, stdout_used=asked)
    tshark_options.check(args, "live", stdout_records=args.write == STDOUT)
    packets_out = binary_stdout(env) if args.write == STDOUT else None
    if packets_out is not None:
        args.quiet = True
    check_format(args.time_format)
    wants_colour(args.color, env.stdout, env.environ)  # (a wrong --color before anything is received)
    dialect = load_dialect(args.dialect)
    source = make_source(args, env)
    try:
        source.open()
    except BaseException:
        source.close()
        raise
    clock = Clock(args.time_format, None)  # (its first time: the first record's, below)
    printer: FramePrinter | FieldsWriter = FramePrinter(
        env.stdout, env.stdout_bytes, dialect, args.format, verbose=args.verbose, hex=args.hex, quiet=args.quiet,
        clock=clock if args.time_format != "r" else None,
        colour=args.format == "text" and wants_colour(args.color, env.stdout, env.environ))
    if args.format == "fields" and not args.quiet:
        from mavscope.fields.registry import FieldRegistry
        from mavscope.output.fields_out import FieldsWriter, parse_format

        printer = FieldsWriter(env.stdout, FieldRegistry(dialect), args.fields, parse_format(args.field_options),
                               clock)
    zstats = None
    if args.statistics:
        from mavscope.output.zstats import ZStats

        zstats = ZStats(args.statistics, dialect, None)  # (its t0: the first record's, below)
    writer: LivePcapWriter | None = None
    restore: list[tuple[signal.Signals, object]] = []
    timer: threading.Timer | None = None
    stopper = Stopper()
    shown = 0
    problems = Problems(env, "live")
    try:
        if args.write:
            writer = LivePcapWriter(args.write, source.linktype, args.ring, file=packets_out)
        if threading.current_thread() is threading.main_thread():
            def on_signal(signum: int, frame: FrameType | None) -> None:
                source.stop(drain=stopper.signal())  # a second signal: stop draining too

            for sig in (signal.SIGINT, signal.SIGTERM):
                restore.append((sig, signal.signal(sig, on_signal)))
        # the handlers are in place before the line that tells a script it may signal
        env.say(f"live: {describe(source)}")
        env.stderr.flush()

        def idle() -> None:
            printer.flush()
            if writer is not None:
                writer.tick()

        def records() -> Iterator[Record]:
            for rec in source.records(on_idle=idle):
                if clock.t0 is None:
                    clock.t0 = rec.time
                    if isinstance(printer, FramePrinter):
                        printer.t0 = rec.time
                    if zstats is not None:
                        zstats.t0 = rec.time
                clock.captured(rec.number, rec.time)
                if writer is not None:
                    writer.write(rec)  # every datagram received goes to the pcap, decoded or not
                if stopper.decode():
                    yield rec

        if args.duration is not None:
            timer = threading.Timer(args.duration, source.stop)
            timer.daemon = True
        limit = args.count if args.count is not None else -1
        show = printer.frame
        native = _native_lines(args, env, source)
        source.start()
        if timer is not None:
            timer.start()
        try:
            printer.begin()
            if native:
                assert isinstance(printer, FramePrinter)
                shown = _write_native(args, env, source, dialect, stopper, writer, problems, printer)
            else:
                for item in build_pipeline(pipeline_options(args, env), dialect, records(), warn=warner(env),
                                           tap=zstats.frame if zstats is not None else None):
                    if type(item) is Anomaly:
                        problems.anomaly(item)
                        continue
                    show(item)
                    shown += 1
                    if shown == limit:
                        source.stop(drain=False)
                        break
            printer.end()
            if zstats is not None:  # the statistics after the frames, as read -z
                printer.flush()
                zstats.write(env.stdout)
        except BrokenPipeError:
            raise  # `mavscope live ... | head`: main() ends quietly
        except OSError as e:
            raise MavscopeError(f"live: receiving failed: {e.strerror or e}") from None
    finally:
        problems.close()
        if timer is not None:
            timer.cancel()
        source.close()
        for sig, old in restore:
            # after a stop signal the capture is ending: a second one, arriving while the summary is
            # written (a fast stop leaves little time between two), must not kill the process with it
            signal.signal(sig, signal.SIG_IGN if stopper.deadline is not None else old)  # type: ignore[arg-type]
        if writer is not None:
            writer.close()
        try:
            printer.flush()
        finally:
            if isinstance(source, UdpSource) and source.forward is not None:
                env.say(f"live: relayed {source.forwarded} datagrams ({source.forward_errors} could not be relayed)")
            env.say(summary(source, shown, stopper.undecoded), prefix="")
            env.stderr.flush()
    return ExitStatus.OK
