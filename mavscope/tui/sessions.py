"""Where the terminal UI gets its frames: a capture file or a live UDP port, through the same pipeline
as `mavscope read` (no Textual here).

`TuiOptions` is what `mavscope tui` was asked for; the command line builds it, and so do the tests.
A `FrameSource` opens the pipeline without the display filter (the TUI applies that itself, so that it
can change it), collects the stages' warnings for the app to show, and makes the source that results
from adding a key (`replace(options, keys=...)`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

from mavscope.browse.index import FrameIndex
from mavscope.browse.rows import Progress
from mavscope.capture.detect import open_capture
from mavscope.capture.reader import CaptureReader
from mavscope.endpoint import Endpoint
from mavscope.live.udp import UdpSource, parse_endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.native.core import NATIVE
from mavscope.native.index import indexes as native_indexes
from mavscope.native.index import native_build
from mavscope.pipeline.dissect import Anomaly
from mavscope.pipeline.options import PipelineOptions
from mavscope.pipeline.session import build_pipeline, make_security_stage, open_session, peek_time
from mavscope.security.stage import NOTE_CODES, SecurityStage

DEFAULT_KEEP = 200_000


@dataclass(frozen=True, slots=True)
class TuiOptions:
    """What the terminal UI shows: a capture (`path`) or, with `live`, the UDP port `udp`."""

    pipeline: PipelineOptions = field(default_factory=PipelineOptions)
    live: bool = False
    udp: str | None = None  # [HOST:]PORT to listen on (follow mode)
    keep: int = DEFAULT_KEEP  # frames a live index keeps; older ones are dropped


Opened = tuple[object, Iterator[Frame | Anomaly], float | None]  # (reader, pipeline, time of the first record)


class FrameSource:
    """A capture file and the options of its pipeline."""

    live = False

    def __init__(self, path: str, options: PipelineOptions, dialect: Dialect) -> None:
        self.path = path
        self.options = options
        self.dialect = dialect
        self._warnings: list[str] = []  # the stages' warnings: the app shows them (never on its terminal)

    def warn(self, message: str) -> None:
        self._warnings.append(message)

    def pipeline_options(self) -> PipelineOptions:
        return replace(self.options, display_filter=None)

    def open(self) -> Opened:
        """(reader, pipeline, time of the first record)."""
        reader: CaptureReader = open_capture(self.path)
        t0, records = peek_time(iter(reader))
        return reader, build_pipeline(self.pipeline_options(), self.dialect, records, warn=self.warn), t0

    def index_natively(self, index: FrameIndex, on_progress: Callable[[Progress], object],
                       cancelled: Callable[[], bool]) -> bool:
        """Fill `index` through the native engine (mavscope.native.index) when the session runs on it and the
        index reads this kind; False (nothing done) when the pure pipeline must (no extension, MAVSCOPE_PURE,
        a raw stream). The session (open_session) opens the capture, the stages and chooses the engine, as
        for every front end."""
        said: list[str] = []  # the stages' warnings: said once, by the pipeline that reads the capture
        with open_session(self.path, self.pipeline_options(), dialect=self.dialect, warn=said.append) as session:
            if session.engine != NATIVE or not native_indexes(session.reader.kind):
                return False
            for message in said:
                self.warn(message)
            index.t0 = session.t0
            native_build(index, self.path, self.dialect, session.security, on_progress=on_progress,
                         cancelled=cancelled)
        return True

    def check(self) -> None:
        """Build the stages over no records: they parse their options (MavscopeError if one is wrong)."""
        for _ in build_pipeline(self.pipeline_options(), self.dialect, iter(()), warn=self.warn):
            pass

    def messages(self) -> str:
        """What the stages warned about, taken once."""
        text = "\n".join(self._warnings)
        self._warnings.clear()
        return text

    def with_options(self, options: PipelineOptions) -> FrameSource:
        return FrameSource(self.path, options, self.dialect)


class LiveReader:
    """A live source where the index build expects a reader: context manager, `position`, `size`."""

    size = 0
    position = 0

    def __init__(self, source: UdpSource) -> None:
        self.source = source
        self.on_idle: Callable[[], None] = lambda: None

    def __enter__(self) -> LiveReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.source.stop(drain=False)
        self.source.close()


class LiveFrameSource(FrameSource):
    """Follow mode: the frames of a UDP port as they arrive (`--live --udp PORT`), through the same
    pipeline. The index keeps the newest `keep` frames."""

    live = True

    def index_natively(self, index: FrameIndex, on_progress: Callable[[Progress], object],
                       cancelled: Callable[[], bool]) -> bool:
        return False  # frames as they arrive: the pure pipeline

    def __init__(self, listen: str, options: PipelineOptions, dialect: Dialect) -> None:
        super().__init__(f"udp {listen}", options, dialect)
        self.listen: Endpoint = parse_endpoint(listen, what="--udp")
        self.udp: UdpSource | None = None
        self.security: SecurityStage | None = None
        self._keys_lock = threading.Lock()  # the options the stage was built from, and the stage

    def open(self) -> Opened:
        self.udp = src = UdpSource(self.listen)
        src.open()
        src.start()
        self.path = f"udp {src.bound}"
        reader = LiveReader(src)
        records = src.records(on_idle=lambda: reader.on_idle())
        with self._keys_lock:
            opts = self.pipeline_options()
            self.security = make_security_stage(opts, self.warn)
        return reader, build_pipeline(opts, self.dialect, records, security=self.security, warn=self.warn), None

    def add_keys(self, options: PipelineOptions, index: FrameIndex, on_done: Callable[[int], object]) -> None:
        """Take new key options. The capture thread hands them to the running security stage between two
        frames, judges the frames `index` holds again, and calls `on_done(frames judged)`; the frames
        after are checked with them too. MavscopeError (nothing changed) when a spec is wrong."""
        material = make_security_stage(options, self.warn).material  # parses every spec, raises if one is wrong
        with self._keys_lock:
            self.options = options
            if self.security is None:  # not capturing yet: open() builds the stage from these options
                on_done(0)
                return
            self.security.replace_material(material, lambda stage: on_done(index.rejudge(stage.run, NOTE_CODES)))

    def take_keys(self) -> None:
        """On the capture thread while no frame comes: apply keys handed over meanwhile."""
        if self.security is not None:
            self.security.take_material()

    def stop(self) -> None:
        if self.udp is not None:
            self.udp.stop(drain=False)
