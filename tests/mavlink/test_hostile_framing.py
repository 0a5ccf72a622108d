"""Resynchronisation does work linear in the input (defect 14), counted, never timed.

Runs of 0xFD/0xFE bytes were processed 40 times slower than normal input: at every STX of a run the
next-STX search looked for the other STX byte all the way to the end of the buffer (quadratic), and at
the end of a datagram every STX re-checked every later one (quadratic in the frame size). The work is
counted here with a deterministic operation counter: one unit per call of the framer's primitives, plus
one per byte that a search, a run match or a CRC may look at. Outputs must not change: they are
compared with the bundled captures elsewhere, and with an independent expectation here.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest

import mavscope.mavlink.framing as framing
from mavscope.mavlink.framing import Framer, StreamFramer
from tests.support.pmav import heartbeat, mav2, statustext


class Probe(bytes):
    """Bytes whose find() is charged the whole span it may scan."""

    counter: list[int]

    def find(self, sub, start=None, end=None):  # type: ignore[no-untyped-def,override]
        lo = 0 if start is None else start
        hi = len(self) if end is None else min(end, len(self))
        self.counter[0] += max(hi - lo, 0)
        return bytes.find(self, sub, start, end)  # type: ignore[arg-type]


@contextmanager
def counting(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """Count the framer's work while the block runs: [units]."""
    work = [0]

    def calls(fn: Callable) -> Callable:  # type: ignore[type-arg]
        def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
            work[0] += 1
            return fn(*args, **kwargs)
        return counted

    def crc(data: bytes, *rest: object) -> int:
        work[0] += 1 + len(data)
        return orig_crc(data, *rest)  # type: ignore[arg-type]

    orig_crc = framing.mcrf4xx
    orig_scan = Framer.scan

    def scan(self, buf, start, end, final):  # type: ignore[no-untyped-def]
        probe = Probe(buf)
        probe.counter = work
        work[0] += 1
        return orig_scan(self, probe, start, end, final)

    with monkeypatch.context() as mp:  # undone at the end: a second count must not wrap the first's wrappers
        mp.setattr(framing, "mcrf4xx", crc)
        mp.setattr(Framer, "scan", scan)
        mp.setattr(Framer, "candidate", calls(Framer.candidate))
        for name in ("_check_at", "_cut_short", "_next_stx", "_crc_status"):
            mp.setattr(framing, name, calls(getattr(framing, name)))
        runs = getattr(framing, "_RUNS", None)
        if runs is not None:  # the run matcher is charged the bytes it matched
            def charged(match: Callable) -> Callable:  # type: ignore[type-arg]
                def run(buf, pos, end):  # type: ignore[no-untyped-def]
                    m = match(buf, pos, end)
                    work[0] += 1 + (m.end() - pos if m else 0)
                    return m
                return run
            mp.setattr(framing, "_RUNS", {k: charged(v) for k, v in runs.items()})
        yield work


def _mix(n: int, seed: int) -> bytes:
    rng = random.Random(seed)
    return bytes(rng.choice((0xFD, 0xFE)) for _ in range(n))


PATTERNS: dict[str, Callable[[int], bytes]] = {
    "fd-run": lambda n: b"\xfd" * n,
    "fe-run": lambda n: b"\xfe" * n,
    "fd-fe": lambda n: b"\xfd\xfe" * (n // 2),
    "fd-00": lambda n: b"\xfd\x00" * (n // 2),
    "fe-fe-fd": lambda n: b"\xfe\xfe\xfd" * (n // 3),
    "random-stx": lambda n: _mix(n, 7),
    "runs-and-frames": lambda n: (b"\xfe" * 700 + heartbeat(mav2()) + b"\xfd" * 300 + statustext(mav2())) * (n // 1100),
}
# At most, per input byte: a few CRCs of up to 280 bytes (a stream fed a byte at a time re-checks the
# candidate it waits on), calls, searches. The quadratic search charged tens of thousands per byte.
WORK_PER_BYTE = 2000


def _datagram_work(framer: Framer, data: bytes, monkeypatch: pytest.MonkeyPatch) -> int:
    with counting(monkeypatch) as work:
        framer.scan(data, 0, len(data), True)
    return work[0]


@pytest.mark.parametrize("pattern", PATTERNS)
def test_datagram_scan_work_is_linear(dialect, monkeypatch: pytest.MonkeyPatch, pattern: str) -> None:  # type: ignore[no-untyped-def]
    framer = Framer(dialect.messages)
    small, large = PATTERNS[pattern](16_384), PATTERNS[pattern](65_536)
    w_small, w_large = _datagram_work(framer, small, monkeypatch), _datagram_work(framer, large, monkeypatch)
    assert w_large / len(large) <= 1.1 * w_small / len(small), (w_small, w_large)
    assert w_large <= WORK_PER_BYTE * len(large), w_large / len(large)


def _stream_work(framer: Framer, data: bytes, chunk: int, monkeypatch: pytest.MonkeyPatch) -> int:
    with counting(monkeypatch) as work:
        sf = StreamFramer(framer, ("raw",))
        sf.trusted = True
        for i in range(0, len(data), chunk):
            sf.feed(data[i:i + chunk], i // chunk + 1, i)
            sf.take(False)
        sf.take(True)
    return work[0]


@pytest.mark.parametrize("chunk", [1, 100, 65_536])
@pytest.mark.parametrize("pattern", ["fd-run", "fe-run", "fd-fe", "random-stx", "runs-and-frames"])
def test_stream_work_is_linear(dialect, monkeypatch: pytest.MonkeyPatch, pattern: str, chunk: int) -> None:  # type: ignore[no-untyped-def]
    framer = Framer(dialect.messages)
    n = 4_096 if chunk == 1 else 32_768
    small, large = PATTERNS[pattern](n), PATTERNS[pattern](4 * n)
    w_small = _stream_work(framer, small, chunk, monkeypatch)
    w_large = _stream_work(framer, large, chunk, monkeypatch)
    assert w_large / len(large) <= 1.25 * w_small / len(small), (w_small, w_large)  # a bit of warm-up
    assert w_large <= WORK_PER_BYTE * len(large), w_large / len(large)


@pytest.mark.parametrize("pattern", PATTERNS)
def test_runs_are_skipped_whole_and_frames_after_them_found(dialect, pattern: str) -> None:  # type: ignore[no-untyped-def]
    """The verdicts the shortcuts take are the ones checking every position gives: every byte is in a
    frame or a skipped run, the STX runs hold no valid frame, and frames placed among them are found."""
    framer = Framer(dialect.messages)
    hb, st = heartbeat(mav2()), statustext(mav2())
    data = PATTERNS[pattern](20_000)
    found, skipped, resume = framer.scan(data, 0, len(data), True)
    assert resume == len(data)
    assert sum(c for _, c in skipped) + sum(s for _, s, _, _ in found) == len(data)
    if pattern == "runs-and-frames":
        assert [data[p:p + s] for p, s, _, _ in found if s in (len(hb), len(st))] == [hb, st] * (20_000 // 1100)
    elif pattern != "random-stx":  # (random STX bytes may hold a frame whose CRC happens to match)
        assert len(found) <= 1 and all(p + s == len(data) for p, s, _, _ in found)  # a frame ending at the end
    if pattern in ("fd-run", "fe-run"):
        framed = data + hb
        found, _, _ = framer.scan(framed, 0, len(framed), True)
        assert (found[-1][0], found[-1][2]) == (len(data), framing.OK)


@pytest.mark.parametrize("pattern", ["fd-run", "fe-run", "fd-fe", "random-stx"])
def test_short_datagrams_of_stx_bytes(dialect, monkeypatch: pytest.MonkeyPatch, pattern: str) -> None:  # type: ignore[no-untyped-def]
    """A datagram shorter than a frame: every STX in it used to re-check every later one."""
    framer = Framer(dialect.messages)
    datagrams = [PATTERNS[pattern](300)[: 200 + i % 100] for i in range(200)]
    with counting(monkeypatch) as work:
        for d in datagrams:
            framer.scan(d, 0, len(d), True)
    total = sum(len(d) for d in datagrams)
    assert work[0] <= 100 * total, work[0] / total
