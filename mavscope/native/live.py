"""`mavscope live --udp` on the native engine: batched receive, the C walker, the Python pipeline between.

The receiver thread takes datagrams with recvmmsg(2) (mavscope._native.Receiver) and queues them in
Chunks: whole records of a nanosecond pcap, each the Ethernet/IP/UDP packet the pure receiver
synthesises. The consumer feeds them to one native walker over that growing pcap
(`NativeWalk(None, ...).feed`), which writes the JSON Lines (or summary lines) of every clean datagram
and hands the others back to the Python pipeline (dissector, security stage), exactly as `read` does
over a file (mavscope.native.drive). The lines are byte-identical to the pure live path's for the same
datagrams: the records are the same, numbered and timed the same (docs/live.md, docs/native.md).

What the pure path does per record stays per record: `-w` writes every datagram to the pcap (records
split from the Chunk), and a stopping capture counts what it no longer decodes (per Chunk).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Protocol

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.live.sink import LivePcapWriter
from mavscope.live.source import Chunk, LiveSource, chunk_items
from mavscope.live.stop import Stopper
from mavscope.mavlink.dialect import Dialect
from mavscope.mavlink.frame import Frame
from mavscope.native.core import _native
from mavscope.native.summary import summary_for
from mavscope.native.walk import LineSink, NativeWalk, Reporter, drive, share_signing
from mavscope.pipeline.dissect import Dissector
from mavscope.security.stage import SecurityStage


class Output(Protocol):
    """Where the lines go: a binary stream (stdout's bytes), or one that drops them (`-q`)."""

    def write(self, data: bytes | bytearray, /) -> object: ...

    def flush(self) -> object: ...


def _not_built() -> RuntimeError:
    return RuntimeError("mavscope._native is not built")


def receiver_factory() -> Callable[[bytes, int], object] | None:
    """The batch receiver `UdpSource(receiver=...)` takes: the extension's, or None when it is not built."""
    return None if _native is None else _native.Receiver


def pcap_header() -> bytes:
    """The global header of the pcap a Chunk's records belong to."""
    if _native is None:
        raise _not_built()
    return _native.UDP_PCAP_HEADER


def write_live(source: LiveSource, dialect: Dialect, stage: SecurityStage, out: Output, problems: Reporter,
               render: Callable[[Frame], bytes], *, summary: bool, count: int | None, stopper: Stopper,
               writer: LivePcapWriter | None = None, on_t0: Callable[[float], object] | None = None,
               idle: Callable[[], object] | None = None) -> int:
    """The per-frame lines of a live capture from `source` (a batched UdpSource) until it stops: JSON
    Lines, or summary lines (`summary`) with times relative to the first datagram's (told to `on_t0`).
    Stops the source after `count` frames. `idle` is called whenever the queue runs empty (after the
    lines are flushed to `out`). Returns the number of frames written."""
    dissector = Dissector(dialect, stage.material.wifi)
    sink = LineSink(stage, problems, render, out.write, count)
    walk: NativeWalk | None = None
    native_frames = 0
    signing = share_signing(stage)

    def on_idle() -> None:
        out.flush()
        if idle is not None:
            idle()

    try:
        for chunk in source.chunks(on_idle=on_idle):
            if writer is not None:
                _write_pcap(writer, chunk)
            if not stopper.decode_many(chunk.datagrams):
                continue
            if walk is None:
                t0 = source.t0
                if on_t0 is not None and t0 is not None:
                    on_t0(t0)
                walk = NativeWalk(None, dialect, dissector.mavlink_endpoints, stage.signed_senders,
                                  summary=summary_for(dialect) if summary else None, t0=t0,
                                  receivers=dissector.receivers)
                walk.feed(pcap_header() + chunk.records)
            else:
                walk.feed(chunk.records)
            drive(walk, dissector, stage, sink, signing=signing)
            if sink.done:
                source.stop(drain=False)
                break
        if not sink.done:
            sink.python(dissector.finish())
    finally:
        if walk is not None:
            native_frames = walk.stats()["frames_native"]
            walk.close()
    return sink.frames if count is not None else sink.frames + native_frames


def _write_pcap(writer: LivePcapWriter, chunk: Chunk) -> None:
    """The Chunk's records into the pcap, as the pure path writes each Record (microsecond times)."""
    if _native is None:
        raise _not_built()
    micro, count = _native.records_to_micro(chunk.records)
    writer.write_batch(micro, count, lambda: _records(chunk))


def _records(chunk: Chunk) -> Iterator[Record]:
    for t, packet, _payload in chunk_items(chunk.records):
        yield Record(0, t, LINKTYPE_ETHERNET, packet, 0, len(packet))
