"""`live --udp` on the native engine (mavscope.native.live) against the pure path, and its batched receiver.

- The C record maker (`_native.udp_record`) against capture.synth.udp_packet (the pure receiver's
  packet), byte for byte, over address families, ports and payload lengths.
- The whole command, both engines, on the same received datagrams: a source that replays Chunks (the
  UDP payloads of every bundled capture and of the real captures, with times of our choosing) replaces
  the socket; stdout and stderr must be equal with MAVSCOPE_PURE=1 (records() splits the Chunks, the
  Python pipeline writes every line) and without (the native walker over the growing pcap).
- The receivers on loopback: the same datagrams to a batched and a per-datagram UdpSource give the same
  Records but for the receive time.
"""

from __future__ import annotations

import random
import socket
import struct
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from mavscope.capture.base import Record
from mavscope.capture.detect import open_capture
from mavscope.capture.synth import packed_address, udp_packet
from mavscope.endpoint import Endpoint
from mavscope.live.source import Chunk, chunk_items, chunk_prefix
from mavscope.live.udp import UdpSource
from mavscope.transport.decap import Decapsulator
from tests.conftest import CAPTURES, Cli

_native = pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

PURE = {"MAVSCOPE_PURE": "1"}
HOSTS = ["127.0.0.1", "10.1.2.3", "0.0.0.0", "::1", "fe80::1", "2001:db8::ff", "::ffff:192.168.1.2"]


def test_record_maker_matches_udp_packet() -> None:
    rnd = random.Random(7)
    for _ in range(3000):
        sh, dh = rnd.choice(HOSTS), rnd.choice(HOSTS)
        sp, dp = rnd.randrange(65536), rnd.randrange(65536)
        payload = rnd.randbytes(rnd.choice([0, 1, 2, 3, 17, 280, rnd.randrange(3000)]))
        sec, nsec = rnd.randrange(1 << 32), rnd.randrange(1_000_000_000)
        rec = _native.udp_record(sec, nsec, packed_address(sh), sp, packed_address(dh), dp, payload)
        packet = udp_packet(sh, sp, dh, dp, payload)
        assert rec[16:] == packet
        assert struct.unpack_from("<IIII", rec) == (sec, nsec, len(packet), len(packet))
    # the largest IPv4 datagram still fits; one byte more makes an IPv6 packet, as udp_packet decides
    big = bytes(65507)
    assert _native.udp_record(1, 0, packed_address("127.0.0.1"), 1, packed_address("127.0.0.1"), 2, big)[16:] == \
        udp_packet("127.0.0.1", 1, "127.0.0.1", 2, big)
    with pytest.raises(ValueError):
        _native.udp_record(1, 0, packed_address("127.0.0.1"), 1, packed_address("127.0.0.1"), 2, bytes(65508))


def datagrams(path: Path) -> list[tuple[str, int, bytes]]:
    """(source host, source port, payload) of every UDP datagram of a capture, in order."""
    out = []
    decap = Decapsulator()
    with open_capture(path) as reader:
        for rec in reader:
            for p in decap.feed(rec):
                if p.transport == "udp" and p.src is not None:
                    out.append((p.src.host, p.src.port, p.data))
    return out


def chunks_of(items: list[tuple[str, int, bytes]], seed: int) -> list[Chunk]:
    """The datagrams as the native receiver queues them, to 127.0.0.1:14550, in Chunks of random sizes,
    at times 1.7e9 s + 1.25 ms apart with odd nanoseconds (times the receiver could give)."""
    rnd = random.Random(seed)
    local = packed_address("127.0.0.1")
    out: list[Chunk] = []
    i = 0
    while i < len(items):
        n = rnd.choice([1, 2, 5, 64, 300])
        buf = bytearray()
        count = size = 0
        for host, port, payload in items[i : i + n]:
            ns = 1_700_000_000 * 10**9 + i * 1_250_000 + 7 * i % 1000
            buf += _native.udp_record(ns // 10**9, ns % 10**9, packed_address(host), port, local, 14550, payload)
            count += 1
            size += len(payload)
            i += 1
        out.append(Chunk(bytes(buf), count, size))
    return out


class Replay(UdpSource):
    """A UdpSource whose receiver thread queues given Chunks instead of reading a socket."""

    def __init__(self, chunks: list[Chunk]) -> None:
        super().__init__(Endpoint("127.0.0.1", 14550), receiver=lambda addr, port: None)  # type: ignore[arg-type,return-value]
        self.replay = chunks

    def open(self) -> None:
        self.local = ("127.0.0.1", 14550)

    def _receive(self) -> None:
        for c in self.replay:
            self._offer_chunk(c)


def both(cli: Cli, monkeypatch: pytest.MonkeyPatch, chunks: list[Chunk], *argv: str) -> tuple[str, str]:
    import mavscope.native.live

    calls = []
    write_live = mavscope.native.live.write_live

    def spy(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return write_live(*args, **kwargs)

    monkeypatch.setattr(mavscope.native.live, "write_live", spy)
    outputs = []
    for environ in (PURE, {}):
        monkeypatch.setattr("mavscope.commands.live.make_source", lambda args, env: Replay(chunks))
        status, out, err = cli("live", "--udp", "14550", *argv, environ=environ)
        assert status == 0, err
        outputs.append((out, err))
        assert len(calls) == (0 if environ else 1)  # the pure run took records(), the other the native walker
    (pure_out, pure_err), (nat_out, nat_err) = outputs
    assert nat_err == pure_err
    assert nat_out == pure_out
    return nat_out, nat_err


UDP_CAPTURES = sorted(p for p in CAPTURES.glob("*.pcap*") if datagrams(p))


@pytest.mark.parametrize("fmt", [("-T", "jsonl"), ()], ids=["jsonl", "text"])
@pytest.mark.parametrize("path", UDP_CAPTURES, ids=lambda p: p.name)
def test_engines_print_the_same(path: Path, fmt: tuple[str, ...], cli: Cli, monkeypatch: pytest.MonkeyPatch) -> None:
    items = datagrams(path)
    out, _ = both(cli, monkeypatch, chunks_of(items, len(items)), *fmt)
    assert out.count("\n") >= len(items) // 2  # the capture's frames, most datagrams holding one or more


def test_engines_with_count_key_and_pcap(cli: Cli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    items = datagrams(CAPTURES / "signed_udp.pcap")
    chunks = chunks_of(items, 3)
    key = "hex:ac2193ecb3be4d7e444e2867d430a8b1618cd2ac1ed9710d580a79630f5420f0"  # captures/README.md
    for extra in (["-c", "7"], ["-c", "1"], ["--key", key], ["--use-leaked-keys"]):
        both(cli, monkeypatch, chunks, "-T", "jsonl", *extra)
    pcaps = []
    for environ in (PURE, {}):
        monkeypatch.setattr("mavscope.commands.live.make_source", lambda args, env: Replay(chunks))
        out_pcap = tmp_path / f"{len(pcaps)}.pcap"
        assert cli("live", "--udp", "14550", "-T", "jsonl", "-w", out_pcap, environ=environ).status == 0
        pcaps.append(out_pcap.read_bytes())
    assert pcaps[0] == pcaps[1] and len(pcaps[0]) > 24


def test_engines_on_real_captures(real_captures: Path, cli: Cli, monkeypatch: pytest.MonkeyPatch) -> None:
    tried = 0
    for path in sorted(real_captures.glob("*.pcap*")):
        items = datagrams(path)
        if items:
            both(cli, monkeypatch, chunks_of(items, 11), "-T", "jsonl")
            tried += 1
    assert tried >= 2  # ap_sitl_attack1 and ipal_transcriber carry UDP (PROVENANCE.md)


def test_queue_limits_drop_the_tail_of_a_chunk() -> None:
    chunk = chunks_of([("10.0.0.1", 5, bytes(10 + i)) for i in range(10)], 1)
    whole = Chunk(b"".join(c.records for c in chunk), 10, sum(c.size for c in chunk))
    kept = chunk_prefix(whole, 4, 10_000)
    assert kept.datagrams == 4 and kept.size == 10 + 11 + 12 + 13
    assert chunk_prefix(whole, 10, 10 + 11 + 12).datagrams == 3
    src = UdpSource(Endpoint("127.0.0.1", 0), max_items=6)
    src._offer_chunk(whole)
    assert (src.received, src.queue_drops) == (10, 4)
    records = list(_drain(src))
    assert [len(r.data) - 42 for r in records] == [10, 11, 12, 13, 14, 15]
    assert [r.number for r in records] == [1, 2, 3, 4, 5, 6]


def _drain(src: UdpSource) -> Iterator[Record]:
    src._q.put(None)
    return src.records()


def test_batched_and_per_datagram_receivers_give_the_same_records() -> None:
    sources = [UdpSource(Endpoint("127.0.0.1", 0), receiver=_native.Receiver), UdpSource(Endpoint("0.0.0.0", 0))]
    for s in sources:
        s.open()
    try:
        assert sources[0].batched and not sources[1].batched
        payloads = [bytes(range(i % 256)) * (1 + i % 3) for i in range(300)]
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx:
            tx.bind(("127.0.0.1", 0))
            port = tx.getsockname()[1]
            for p in payloads:
                for s in sources:
                    tx.sendto(p, ("127.0.0.1", s.bound.port))
        before = time.time()
        got = []
        for s in sources:
            deadline = time.monotonic() + 10
            while s.received < len(payloads) and time.monotonic() < deadline:
                if not s._take(s.sock, 1024):  # type: ignore[arg-type]
                    time.sleep(0.01)
            got.append(list(_drain(s)))
        for mine, ref in zip(*got, strict=True):
            assert mine.number == ref.number and mine.offset == ref.offset
            # the same packet but for the destination port (each source its own)
            assert mine.data[:36] == ref.data[:36] and mine.data[38:40] == ref.data[38:40]
            assert mine.data[42:] == ref.data[42:]
            assert struct.unpack_from("!H", mine.data, 34)[0] == port
            assert abs(mine.time - before) < 60
        assert [len(r.data) - 42 for r in got[0]] == [len(p) for p in payloads]
    finally:
        for s in sources:
            s.close()


def test_fed_walker_refuses_what_it_cannot_take(dialect) -> None:  # type: ignore[no-untyped-def]
    from mavscope.native.walk import NativeWalk

    with NativeWalk(CAPTURES / "px4_sitl_udp.pcap", dialect, set(), set()) as walk:
        with pytest.raises(TypeError):
            walk.feed(b"")
    walk = NativeWalk(None, dialect, set(), set())
    walk.feed(_native.UDP_PCAP_HEADER + b"\x01\x00")  # a record header cut short: the walk ends with a note
    assert [b.record for b in walk.batches()][-1] is not None
    with pytest.raises(ValueError):
        walk.feed(b"more")
    walk.close()
    with pytest.raises(ValueError):
        walk.feed(b"")


def test_micro_records_as_the_pcap_writer_writes_them() -> None:
    """records_to_micro against PcapWriter.write of the pure path's Record time (sec + nsec / 1e9), on
    times where rounding decides: half microseconds (half to even), a carry into the next second, the
    last second the format holds."""
    import io

    from mavscope.capture.writer import PcapWriter

    local = packed_address("127.0.0.1")
    times = [(1_700_000_000, n) for n in (0, 499, 500, 1500, 2500, 999_999_499, 999_999_500, 999_999_999)]
    times += [(0, 0), (1, 500), ((1 << 32) - 1, 999_999_999), ((1 << 32) - 1, 0)]
    rnd = random.Random(5)
    times += [(rnd.randrange(1 << 32), rnd.randrange(10**9)) for _ in range(2000)]
    batch = b"".join(_native.udp_record(sec, ns, local, 1, local, 2, b"x" * (i % 5))
                     for i, (sec, ns) in enumerate(times))
    micro, count = _native.records_to_micro(batch)
    assert count == len(times)
    ref = io.BytesIO()
    writer = PcapWriter(ref, 1)
    for t, packet, _ in chunk_items(batch):
        writer.write(t, packet, len(packet))
    assert micro == ref.getvalue()[24:]
    with pytest.raises(ValueError):
        _native.records_to_micro(batch[:-1])


def test_engines_quiet_and_ring(cli: Cli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    items = datagrams(CAPTURES / "px4_sitl_udp.pcap")
    chunks = chunks_of(items, 5)
    out, err = both(cli, monkeypatch, chunks, "-q")
    assert out == "" and int(err.splitlines()[-1].split()[2]) > len(items) // 2  # "mavscope: live: N frames, ..."
    files = []
    for environ in (PURE, {}):
        monkeypatch.setattr("mavscope.commands.live.make_source", lambda args, env: Replay(chunks))
        out = tmp_path / f"ring{len(files)}.pcap"
        assert cli("live", "--udp", "14550", "-q", "-w", out, "--ring", "0.1", environ=environ).status == 0
        files.append((out.read_bytes(), Path(f"{out}.1").read_bytes()))
    assert files[0] == files[1]
