"""The assembled pipeline: the one place where the stages after the dissector are put together.

Every front end gets its frames here: `read`, the analysis commands, `verify` and `audit` through
`open_session(path, options)`; live capture and the TUI's follow mode through `build_pipeline`, which
takes records as they arrive. Stages are added in data-path order: the dissector (records -> frames),
the security stage (signature verdicts, decryption, key-free notes: it always runs), then the display
filter, which comes last so that it can test every verdict.

This module sits above `mavscope.security` and `mavscope.filter` in the layering (it composes them);
the rest of `mavscope.pipeline` sits below them.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from mavscope.capture.base import Record
from mavscope.capture.detect import open_capture
from mavscope.capture.reader import CaptureReader
from mavscope.capture.stream import STDIN
from mavscope.mavlink.dialect import Dialect, load_dialect
from mavscope.mavlink.frame import Frame
from mavscope.native import windows
from mavscope.native.core import NATIVE, PURE
from mavscope.pipeline.batch import FrameBatch, Tables
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.pipeline.options import PipelineOptions
from mavscope.security.keys import KEYRING_ENV, build_material
from mavscope.security.stage import SecurityStage

if TYPE_CHECKING:  # the filter compiler is imported by make_filter, when a filter is given
    from mavscope.filter import DisplayFilter

Warn = Callable[[str], object]
BATCH = 4096  # frames per batch the Python pipeline's frames are given in (Session.batches)


def _quiet(_message: str) -> None:
    return None


def make_security_stage(options: PipelineOptions, warn: Warn = _quiet) -> SecurityStage:
    """The security stage for the key material in `options` (UsageError if a spec is wrong).

    Without key material it still gives the key-free verdicts (unsigned frames in signed streams,
    leaked keys, SecureMAV's test cipher)."""
    environ = {KEYRING_ENV: options.keyring} if options.keyring else {}
    material = build_material(options.keys, options.ciphers, options.ecdh_private,
                              use_leaked_keys=options.use_leaked_keys, environ=environ, warn=warn,
                              wifi=options.wifi_keys)
    return SecurityStage(material)


def make_filter(options: PipelineOptions, dialect: Dialect, warn: Warn = _quiet) -> DisplayFilter | None:
    """The compiled display filter of `options` (FilterError if it does not compile), None without one; what
    it may not mean (a scaled field against a number in its display unit) goes to `warn`."""
    if not options.display_filter:
        return None
    from mavscope.filter import compile_filter

    flt = compile_filter(options.display_filter, dialect)
    for message in flt.warnings:
        warn(f"warning: -Y: {message}")
    return flt


def filter_stage(flt: DisplayFilter, items: Iterable[Frame | Anomaly]) -> Iterator[Frame | Anomaly]:
    """The frames `flt` matches; anomalies (which belong to no frame) pass through."""
    matches = flt.matches
    for item in items:
        if type(item) is Anomaly or matches(item):
            yield item


def build_pipeline(options: PipelineOptions, dialect: Dialect, records: Iterable[Record], *,
                   security: SecurityStage | None = None, warn: Warn = _quiet,
                   tap: Callable[[Frame], object] | None = None) -> Iterator[Frame | Anomaly]:
    """Frames and anomalies of `records` after every stage `options` asks for, display filter included;
    `tap` gets every frame before the filter (statistics count every frame, whatever it shows).

    Live capture passes its own `security` stage, to hand it keys while it runs."""
    if security is None:
        security = make_security_stage(options, warn)
    flt = make_filter(options, dialect, warn)
    items = security.run(Dissector(dialect, security.material.wifi).run(records))
    if tap is not None:
        items = tapped(items, tap)
    return filter_stage(flt, items) if flt is not None else items


def tapped(items: Iterator[Frame | Anomaly], take: Callable[[Frame], object]) -> Iterator[Frame | Anomaly]:
    """`items`, each frame given to `take` as it passes."""
    for item in items:
        if type(item) is not Anomaly:
            take(item)
        yield item


@dataclass
class Session:
    """An open capture and its pipeline.

    `items` are every frame and anomaly after the security stage; `shown()` applies the display filter
    on top. Analyses that must see every frame (sequence numbers, request/answer pairs) read `items`
    and ask `display_filter` which rows to report."""

    path: str
    reader: CaptureReader
    dialect: Dialect
    items: Iterator[Frame | Anomaly]
    security: SecurityStage
    display_filter: DisplayFilter | None
    t0: float | None  # time of the capture's first record: relative times count from it (as tshark's)
    frame_count: int = 0  # frames that came out of the security stage so far (before the filter)
    walked: dict[str, int] = field(default_factory=dict)  # the native walker's counts (size...), when it ran
    environ: Mapping[str, str] | None = None  # the environment the engine is chosen by (MAVSCOPE_PURE)
    engine: str = PURE  # NATIVE where the native walker reads this capture: chosen here, once
    # called with every capture record as the Python pipeline reads it (`items`), before its frames
    record_hooks: list[Callable[[Record], object]] = field(default_factory=list)

    def _watched(self, records: Iterator[Record]) -> Iterator[Record]:
        """The records, each shown first to every hook of `record_hooks` (read -t d: every record's time)."""
        hooks = self.record_hooks
        for rec in records:
            for hook in hooks:
                hook(rec)
            yield rec

    def _counted(self, items: Iterator[Frame | Anomaly]) -> Iterator[Frame | Anomaly]:
        for item in items:
            if type(item) is not Anomaly:
                self.frame_count += 1
            yield item

    @property
    def name(self) -> str:
        """The path as printable text: bytes that are not UTF-8 (a Latin-1 file name) as \\xNN escapes, so
        that JSON and a UTF-8 terminal can carry it."""
        return os.fsencode(self.path).decode("utf-8", "backslashreplace")

    def shown(self) -> Iterator[Frame | Anomaly]:
        """The items after the display filter (all of them without one)."""
        return self.items if self.display_filter is None else filter_stage(self.display_filter, self.items)

    def frames(self) -> Iterator[Frame]:
        """Every frame (no anomalies, no filter)."""
        return (item for item in self.items if type(item) is not Anomaly)

    def batches(self, report: Callable[[Frame | Anomaly], object]) -> Iterator[FrameBatch]:
        """Every frame (no filter) as column batches, in capture order; `report` gets each anomaly and each
        frame with notes that may tell of capture damage, in capture order too (the rows whose notes a
        native chunk gives as codes tell of none: a bad CRC, an unsigned frame of a signing sender). On the
        session's `engine` (open_session chose it: native where the extension is built, MAVSCOPE_PURE is not
        set in `environ` and the walker reads the capture's kind): the native walker's windows
        (native.windows.batches), else the Python pipeline's frames BATCH at a time."""
        tables = Tables()
        if self.engine == NATIVE:
            for b in windows.batches(self.path, self.reader.kind, self.dialect, self.security, report, tables,
                                     stats=self.walked):
                self.frame_count += b.n
                yield b
            return
        chunk: list[Frame] = []
        for item in self.items:
            if type(item) is Anomaly:
                report(item)
                continue
            if item.notes:
                report(item)
            chunk.append(item)
            if len(chunk) == BATCH:
                yield FrameBatch.of_frames(chunk, tables)
                chunk = []
        if chunk:
            yield FrameBatch.of_frames(chunk, tables)


def peek_time(records: Iterator[Record]) -> tuple[float | None, Iterator[Record]]:
    """The time of the first record, and the records with that one put back."""
    head = next(records, None)
    if head is None:
        return None, iter(())
    return head.time, itertools.chain((head,), records)


@contextmanager
def open_session(path: str, options: PipelineOptions, *, dialect: Dialect | None = None,
                 warn: Warn = _quiet, environ: Mapping[str, str] | None = None) -> Iterator[Session]:
    """Open the capture at `path` and build its pipeline (CaptureError, UsageError, FilterError when the
    file or the options are wrong; `warn` receives warnings such as a keyring readable by others; `environ`:
    the environment the engine is chosen by, os.environ when None). The engine is chosen here, once
    (`Session.engine`): every front end that can run on the native walker asks the session which."""
    if dialect is None:
        dialect = load_dialect(options.dialects)
    with open_capture(path) as reader:
        t0, records = peek_time(iter(reader))
        security = make_security_stage(options, warn)
        flt = make_filter(options, dialect, warn)
        # (standard input is the Python readers': the native walker reads a file by offset)
        native = windows.available(environ) and reader.kind in windows.KINDS and path != STDIN
        session = Session(path, reader, dialect, iter(()), security, flt, t0, environ=environ,
                          engine=NATIVE if native else PURE)
        watched = session._watched(records)
        session.items = session._counted(security.run(Dissector(dialect, security.material.wifi).run(watched)))
        yield session
