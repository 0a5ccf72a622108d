"""The native engine of `read -T jsonl`: the optional C extension `mavscope._native` and its Python side.

The C walker reads a capture's records (with pread, never a memory mapping) and writes the JSON Lines of
every record whose frames are all clean (docs/native.md says exactly which); every other record is
handed back, in capture order, to the Python pipeline (`Dissector.feed`, then the security stage), whose
output is the reference. The two paths share their state explicitly: the dissector's
`mavlink_endpoints` and the security stage's `signed_senders` are the very sets the walker reads before
each batch and adds to after it, `Dissector.passed` is told of the records each batch walked, and the
signature verifier's replay state is a `_native.SigningState` the walker judges known streams against.

- The extension's import and the engine choice (`engine(environ)`) are mavscope.native.core's.
- `table_for(dialect)` (mavscope.native.tables): the compiled `_native.Table` of the message layouts,
  from `native.table_blob.build_table` (mavscope's MessageDef/FieldDef, so pymavlink's parser), never
  written by hand.
- `NativeWalk`: the batch walker over a capture file: `Batch`es of JSON text and handed-back Records.
- `write_jsonl(...)`: the whole `read -T jsonl` output of a capture, both paths interleaved.

In the layering this module sits with the front ends (output, commands): like `pipeline.session` it
composes the dissector and the security stage, and it writes the JSON Lines of `output.jsonout`.
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import IO, NamedTuple, Protocol

import orjson

from mavscope.capture.base import Record
from mavscope.capture.detect import detect_kind
from mavscope.capture.reader import WINDOW, handed_back_record, open_file
from mavscope.endpoint import Endpoint
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.mavlink.framing import bad_crc_note
from mavscope.native.core import KINDS, _native
from mavscope.native.tables import table_for
from mavscope.output.jsonout import jsonl_bytes
from mavscope.pipeline.dissect import MAVLINK_PORTS, Anomaly, Dissector, RawLink, Receivers
from mavscope.security.stage import SecurityStage, unsigned_note

BATCH_BYTES = 1 << 20  # JSON text per batch handed to Python


_NAME, _SENDER, _OFFSET = "\x01", "\x02", 7_777_777_777_777  # where the walker writes its own


Template = tuple[bytes, ...]  # a note's JSON cut where its values go


def note_templates() -> tuple[Template, Template, Template]:
    """The JSON of the notes the native walker writes itself, each cut where its values go (walk.h
    MS_TPL_*), made by the functions that make them on the Python path, so each text has one definition:
    security.stage.unsigned_note for a MAVLink 2 and a MAVLink 1 frame (the message's name, the sender
    "sysid/compid", the offset) and framing.bad_crc_note (the CRC's 4 hex digits, the offset)."""
    def unsigned(version: int) -> Template:
        text = orjson.dumps(unsigned_note(version, _NAME, _SENDER, _OFFSET)[1].to_json())
        a, rest = text.split(b"\\u0001")
        b, rest = rest.split(b"\\u0002")
        c, d = rest.split(str(_OFFSET).encode())
        return a, b, c, d

    text = orjson.dumps(bad_crc_note(_NAME, _OFFSET).to_json())
    a, rest = text.split(b"\\u0001")
    b, c = rest.split(str(_OFFSET).encode())
    return unsigned(2), unsigned(1), (a, b, c)


# (number, time, index) of the last record a batch walked natively: what Dissector.passed is told
Walked = tuple[int, float | None, int | None]


class Batch(NamedTuple):
    """One step of the walk, in capture order: records walked natively (the last of them `walked`, their
    JSON Lines `text`), then at most one record handed back to the Python pipeline."""

    walked: Walked | None
    text: bytes | bytearray | None
    record: Record | None


class NativeWalk:
    """A capture file walked in C: `Batch`es of finished JSON Lines and Records handed back for Python.

    The file is opened here (CaptureError as the readers raise it) and read by the walker with pread, a
    `window` of bytes at a time as the Python readers read it (the tests make it small).
    With `summary` (a `_native.Summary`, mavscope.native.summary) the text is summary lines, their
    times relative to `t0`, instead of JSON Lines.
    `endpoints` and `signed_senders` are the Python sets both paths share (the dissector's
    `mavlink_endpoints` and the security stage's `signed_senders`), `receivers` the dissector's (a
    datagram to a destination whose receivers are in a frame is handed back). `signed_nokey()` is asked before
    each batch whether signed frames may be written natively (no signing key configured: `no-key`).
    The walker stops after each handed-back record, so what Python does with it (keys learnt, senders
    seen signing) holds for the records after it.
    With `raw` (the dissector's RawLink) a raw stream's clean stretches are written natively and only the
    pieces around damage handed back (as records of the stream's bytes, with their file offset): the walker
    numbers its frames on from `raw.frames` and reads `raw.held` before each batch (docs/native.md).
    """

    def __init__(self, path: str | os.PathLike[str] | None, dialect: Dialect, endpoints: set[Endpoint],
                 signed_senders: set[tuple[int, int]], kind: str | None = None, window: int = WINDOW,
                 summary: _native.Summary | None = None, t0: float | None = None,
                 receivers: Receivers | None = None, raw: RawLink | None = None) -> None:
        if _native is None:
            raise RuntimeError("mavscope._native is not built")
        self._file: IO[bytes] | None = None
        if path is None:  # a pcap that grows: `feed` it whole records (live capture, mavscope.native.live)
            self.kind, self.path, self.opened_size, fd = "pcap", "", 0, -1
        else:
            self.kind = kind or detect_kind(path)
            self.path, self._file, self.opened_size = open_file(path)
            fd = self._file.fileno()
        try:
            self.walker = _native.Walker(fd, self.opened_size, KINDS[self.kind], table_for(dialect), endpoints,
                                         Endpoint.from_packed, signed_senders, window, summary, t0,
                                         receivers=receivers, notes=note_templates(),
                                         ports=tuple(sorted(MAVLINK_PORTS)), raw=raw)
        except BaseException:
            self.close_file()
            raise

    def feed(self, records: bytes) -> None:
        """More of a walk made without a path: whole pcap records (the global header first). The walk's
        batches() then goes on from where the last one ended."""
        self.walker.feed(records)

    def close_file(self) -> None:
        if self._file is not None:
            self._file.close()

    def batches(self, signed_nokey: Callable[[], bool] = lambda: False, limit: int = BATCH_BYTES,
                buffers: Callable[[], bytearray | None] | None = None,
                signing: Callable[[], _native.SigningState | None] = lambda: None) -> Iterator[Batch]:
        """The walk, batch by batch.

        The text comes as bytes, or, with `buffers`, in the bytearray it returns for each batch (the
        caller recycles them once written: their memory stays mapped, where a new 1 MiB bytes object
        costs fresh pages every batch). `signing()`, asked before each batch: the verifier's
        `_native.SigningState` (signed frames of streams it knows are judged in C), or None.
        """
        walk = self.walker.next
        walked = self.walker.walked
        spare: bytearray | None = None  # a buffer a batch without text did not use: the next one takes it
        told: Walked | None = None
        while True:
            buf = spare if spare is not None else (buffers() if buffers is not None else None)
            segs = walk(signed_nokey(), limit, buf, signing())
            if segs is None:
                # records at the end that gave no text (a UDP datagram without payload): the
                # dissector must still hear of them, as stream frames the capture's end completes
                # belong to its last record
                last = walked()
                if last is not None and last != told:
                    yield Batch(last, None, None)
                return
            text: bytes | bytearray | None = None
            record: Record | None = None
            for seg in segs:
                if isinstance(seg, tuple):
                    record = handed_back_record(seg)
                else:
                    text = seg
            spare = buf if buf is not None and text is not buf else None
            told = walked()
            yield Batch(told, text, record)

    @property
    def position(self) -> int:
        """The file offset the walk has reached (for a progress bar)."""
        return int(self.walker.stats()["position"])

    @property
    def size(self) -> int:
        """The file size: smaller than when opened if the file shrank while it was read."""
        return int(self.walker.stats()["size"])

    def stats(self) -> dict[str, int]:
        """Records written natively, records handed back, frames written natively, file position and size."""
        out: dict[str, int] = self.walker.stats()
        return out

    def close(self) -> None:
        self.walker.close()
        self.close_file()

    def __enter__(self) -> NativeWalk:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class _Writer:
    """Writes byte chunks to `out` on a thread of its own, in the order they are put.

    The walk runs in C without the GIL, and a write(2) to a file releases it too: with two cores the
    JSON text of the next batch is made while the last one is copied to the file. The walker's batches
    come in bytearrays of a small pool (`buffer()`), given back once written, so the process does not
    map fresh memory for every batch. What waits to be written is bounded: `depth` pooled bytearrays, and
    at most QUEUED chunks in all (the Python pipeline's lines come as bytes, a chunk per handed-back record,
    which a slow reader of `out` would otherwise let pile up). An error of `out` (a closed pipe) is raised
    again in the producing thread by `put`, `buffer` or `close`.
    """

    QUEUED = 64

    def __init__(self, out: IO[bytes], depth: int = 8) -> None:
        self.out = out
        self.queue: queue.Queue[bytes | bytearray | None] = queue.Queue(max(self.QUEUED, depth + 1))
        self.free: queue.Queue[bytearray] = queue.Queue()
        for _ in range(depth):
            self.free.put(bytearray())
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, name="mavscope-jsonl-writer", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        write = self.out.write
        get = self.queue.get
        while True:
            chunk = get()
            if chunk is None:
                return
            if self.error is None:
                try:
                    write(chunk)
                except BaseException as exc:  # noqa: BLE001 - handed to the producing thread
                    self.error = exc
            if type(chunk) is bytearray:
                self.free.put(chunk)

    def buffer(self) -> bytearray:
        """A bytearray for the next batch (waits while every one is queued for writing)."""
        if self.error is not None:
            raise self.error
        return self.free.get()

    def put(self, chunk: bytes | bytearray) -> None:
        if self.error is not None:
            raise self.error
        self.queue.put(chunk)

    def close(self) -> None:
        """Wait until everything put is written; raise the writing error if there was one."""
        self.queue.put(None)
        self.thread.join()
        if self.error is not None:
            raise self.error


class Reporter(Protocol):
    """Where problems go (commands.common.Problems): anomalies, and frames whose notes tell of damage."""

    def anomaly(self, item: Anomaly) -> None: ...

    def frame(self, frame: Frame) -> None: ...


class LineSink:
    """The lines of both paths, in order, into `put`: native text as it comes, and `render(frame)` of the
    frames the security stage gives for the Python pipeline's items (anomalies and frames with notes to
    `problems`). Counts the frames written (`frames`); with `count`, stops after that many (`left`
    reaches 0: `done`)."""

    LINES = 512

    def __init__(self, stage: SecurityStage, problems: Reporter, render: Callable[[Frame], bytes],
                 put: Callable[[bytes | bytearray], object], count: int | None = None) -> None:
        self.run = stage.run
        self.problems = problems
        self.render = render
        self.put = put
        self.counting = count is not None
        self.left = -1 if count is None else count
        self.frames = 0  # written by Python, or every frame when counting

    @property
    def done(self) -> bool:
        return not self.left

    def python(self, items: Iterator[Frame | Anomaly] | list[Frame | Anomaly] | list[Anomaly]) -> None:
        """The lines of the frames the Python pipeline makes of `items`, put in chunks of at most LINES lines
        (the frames a capture's end releases from TCP reassembly can be many: 100,000 segments out of
        order held 400 MB of lines when they were put at once)."""
        lines: list[bytes] = []
        problems, render = self.problems, self.render
        for item in self.run(items):
            if type(item) is Anomaly:
                problems.anomaly(item)
                continue
            if item.notes:
                problems.frame(item)
            lines.append(render(item))
            self.left -= 1
            if not self.left:
                break
            if len(lines) >= self.LINES:
                self._put(lines)
                lines = []
        if lines:
            self._put(lines)

    def _put(self, lines: list[bytes]) -> None:
        self.frames += len(lines)
        self.put(b"".join(lines))

    def native(self, text: bytes | bytearray) -> None:
        left = self.left
        if left < 0:
            self.put(text)
            return
        n = text.count(b"\n")
        if n >= left:  # the frame `count` ends in this text
            end = -1
            for _ in range(left):
                end = text.index(b"\n", end + 1)
            text = bytes(memoryview(text)[: end + 1])
            n = left
        self.put(text)
        self.frames += n
        self.left -= n


def share_signing(stage: SecurityStage) -> Callable[[], _native.SigningState | None]:
    """Make `stage` keep its signature replay state in a `_native.SigningState` (before it has judged any
    frame), and return what the walker is given before each batch: the verifier's store (the stage may
    start over with new material), or None when it is not one."""
    if _native is None:
        raise RuntimeError("mavscope._native is not built")
    state_type = _native.SigningState
    stage.use_signing_store(state_type)  # the verifier's replay state is the one the walker judges with

    def signing() -> _native.SigningState | None:
        store = stage.verifier.store
        return store if type(store) is state_type else None

    return signing


def drive(walk: NativeWalk, dissector: Dissector, stage: SecurityStage, sink: LineSink,
          buffers: Callable[[], bytearray | None] | None = None,
          progress: Callable[[int], None] | None = None,
          signing: Callable[[], _native.SigningState | None] = lambda: None) -> None:
    """The walk's batches into `sink` until the walk's end (or `sink.done`): native text as it is, the
    handed-back records through `dissector` (told first of the records walked natively before them);
    `progress` with the file offset after each native batch; `signing` (share_signing) before each
    batch. What the dissector still holds at the end is the caller's (`dissector.finish()`)."""
    nokey: Callable[[], bool] = lambda: not stage.check_signatures  # noqa: E731 - asked per batch
    passed = dissector.passed
    python = sink.python
    for walked, text, record in walk.batches(nokey, buffers=buffers, signing=signing):
        if walked is not None:
            held = passed(*walked)  # a run of tlog text entries ends before these records
            if held:
                python(held)
        if text is not None and not sink.done:
            sink.native(text)
            if progress is not None:
                progress(walk.position)
        if record is not None and not sink.done:
            python(dissector.feed(record))
        if sink.done:
            return


def write_jsonl(path: str | os.PathLike[str], dialect: Dialect, stage: SecurityStage, out: IO[bytes],
                problems: Reporter, threaded: bool = True, progress: Callable[[int], None] | None = None,
                kind: str | None = None, window: int = WINDOW) -> dict[str, int]:
    """`read -T jsonl` of a whole capture: native JSON text and, for handed-back records, the Python
    pipeline (dissector, security stage, jsonl_bytes) in between, in capture order. Anomalies and the
    frames with notes go to `problems`, as the pure path reports them. With `threaded` the writing to
    `out` happens on a thread of its own (_Writer); `progress` is called with the file offset reached
    after each native batch; `window` is the walker's read size. Returns the walk's counters, `frames`
    (every frame written) and `size`."""
    return write_lines(path, dialect, stage, out, problems, jsonl_bytes, threaded=threaded, progress=progress,
                       kind=kind, window=window)


def write_lines(path: str | os.PathLike[str], dialect: Dialect, stage: SecurityStage, out: IO[bytes],
                problems: Reporter, render: Callable[[Frame], bytes], *, summary: _native.Summary | None = None,
                t0: float | None = None, count: int | None = None, threaded: bool = True,
                progress: Callable[[int], None] | None = None, kind: str | None = None,
                window: int = WINDOW) -> dict[str, int]:
    """One line per frame of a whole capture, both paths interleaved in capture order: the walker's text
    (JSON Lines, or summary lines with `summary`) and, for handed-back records, the Python pipeline with
    `render(frame)` (the same line as bytes). `count`: stop after that many frames (`read -c`), as the
    pure path's loop stops. See write_jsonl for the rest."""
    dissector = Dissector(dialect, stage.material.wifi)
    writer = _Writer(out) if threaded else None
    put = writer.put if writer is not None else out.write
    if writer is not None:
        buffers = writer.buffer
    else:
        only = bytearray()  # written before the next batch: one serves
        buffers = lambda: only  # noqa: E731
    sink = LineSink(stage, problems, render, put, count)
    signing = share_signing(stage)
    try:
        with NativeWalk(path, dialect, dissector.mavlink_endpoints, stage.signed_senders, kind, window,
                        summary, t0, receivers=dissector.receivers, raw=dissector.raw) as walk:
            drive(walk, dissector, stage, sink, buffers, progress, signing)
            stats = walk.stats()
        if not sink.done:
            sink.python(dissector.finish())
    finally:
        if writer is not None:
            writer.close()
    stats["frames"] = sink.frames if count is not None else sink.frames + stats["frames_native"]
    return stats
