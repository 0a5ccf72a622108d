"""Guessing signing keys: the well-known keys (tried by every audit), and dictionary attacks on the
passphrase with SHA-256 (MAVProxy, older QGroundControl) or QGroundControl's PBKDF2 (`audit --wordlist`).

Each signing stream (sysid, compid, link id) has its own key, so each gives its own targets (a few of
its signed frames with a good CRC, not only the first: `Targets`). Every guess is tried against every
stream still unsolved, so a capture signed with two keys gives both in one pass, and forged signed
frames placed first cannot hide the key. The wordlist is read line by line (lines longer than MAX_WORD
are skipped and counted), so its size costs time, not memory.

The findings that print a secret are `weak-passphrase` and `default-key`: reporting the passphrase or
the well-known key that was found is the point of these audits (docs/security.md).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from hmac import compare_digest

from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.notes import Finding, finding
from mavscope.security.keys import QGC_ITERATIONS, QGC_SALT

MAX_WORD = 1024  # bytes; a longer line is not a passphrase (a binary file given as a wordlist)
MAX_NO_NEWLINE = 1 << 20  # bytes without a line break after which a file is not a wordlist
MAX_TARGETS = 1024  # signing streams remembered
# Keys that ship as defaults or that a careless setup produces; tried by every audit.
WELL_KNOWN_KEYS: tuple[tuple[str, bytes], ...] = (
    ("the all-zero key", bytes(32)),
    ("SHA-256 of an empty passphrase", hashlib.sha256(b"").digest()),
)

Stream = tuple[int, int, int]  # (sysid, compid, link_id)


class Targets:
    """Target frames of each signing stream: its 1st, 2nd, 16th and 256th signed frame with a good CRC.
    A key is the stream's when it verifies one of them, so forged signed frames placed first (the only
    frames an audit of the first frame would try) cannot hide the stream's key."""

    POSITIONS = frozenset({1, 2, 16, 256})

    def __init__(self) -> None:
        self.frames: dict[Stream, list[Frame]] = {}
        self.seen: dict[Stream, int] = {}

    def add(self, f: Frame) -> None:
        sig = f.signature
        if sig is None or f.crc_status is not CrcStatus.OK:
            return
        stream = (f.sysid, f.compid, sig.link_id)
        n = self.seen.get(stream, 0) + 1
        if n == 1 and len(self.seen) >= MAX_TARGETS:
            return
        self.seen[stream] = n
        if n in self.POSITIONS:
            self.frames.setdefault(stream, []).append(f)

    def add_run(self, stream: Stream, count: int, frame_at: Callable[[int], Frame]) -> None:
        """`count` signed frames with a good CRC of `stream`, as that many `add()` calls in capture order;
        `frame_at(i)` gives the i-th of them (from 0) where one is kept. Streams must come in the order of
        their first frames (the limit of streams counts those seen before)."""
        n = self.seen.get(stream, 0)
        if count <= 0 or (n == 0 and len(self.seen) >= MAX_TARGETS):
            return
        self.seen[stream] = n + count
        for p in sorted(self.POSITIONS):
            if n < p <= n + count:
                self.frames.setdefault(stream, []).append(frame_at(p - n - 1))


Candidates = dict[Stream, list[tuple[int, bytes, bytes]]]  # stream -> [(record, signed data, mac)]


def _candidates(targets: dict[Stream, list[Frame]]) -> Candidates:
    return {s: [(f.record, f.raw[:-6], f.raw[-6:]) for f in fs] for s, fs in targets.items()}


def _verifies(base: object, cands: list[tuple[int, bytes, bytes]]) -> int | None:
    """The record of the first candidate frame whose MAC the key (hashed into `base`) verifies."""
    for record, body, mac in cands:
        h = base.copy()  # type: ignore[attr-defined]
        h.update(body)
        if compare_digest(h.digest()[:6], mac):
            return record
    return None


def _stream_text(stream: Stream) -> str:
    return f"{stream[0]}/{stream[1]} link {stream[2]}"


def try_keys(targets: dict[Stream, list[Frame]], keys: Iterable[tuple[str, bytes]]) -> dict[Stream, tuple[str, int]]:
    """(label, frame it verifies) of the key (from `keys`: (label, 32-byte key)) that signs each stream."""
    found: dict[Stream, tuple[str, int]] = {}
    cands = _candidates(targets)
    for label, key in keys:
        base = hashlib.sha256(key)
        for s, c in cands.items():
            if s not in found:
                record = _verifies(base, c)
                if record is not None:
                    found[s] = (label, record)
    return found


def default_key_findings(targets: dict[Stream, list[Frame]]) -> list[Finding]:
    """A finding per signing stream whose frames verify with a well-known key."""
    return [finding("default-key", f"stream {_stream_text(stream)} signs with {label}: anyone can sign frames "
                                   f"it accepts (frame {record} verifies)", (record,))
            for stream, (label, record) in try_keys(targets, WELL_KNOWN_KEYS).items()]


class Wordlist:
    """The words of a wordlist file, one per line, read as they are used: its size costs time, not memory.

    A line longer than MAX_WORD is not a passphrase and is skipped (`skipped`); after MAX_NO_NEWLINE bytes
    without a line break the file is not a wordlist (/dev/zero, a binary) and reading stops (`stopped`)."""

    def __init__(self, path: str) -> None:
        self.path = path
        self.skipped = 0
        self.stopped: str | None = None
        with open(path, "rb"):
            pass  # OSError now, before any work, if it cannot be read

    def __iter__(self) -> Iterator[bytes]:
        with open(self.path, "rb") as fh:
            run = 0  # bytes read since the last line break
            while True:
                line = fh.readline(MAX_WORD + 2)
                if not line:
                    return
                if not line.endswith(b"\n"):
                    run += len(line)
                    if run > MAX_NO_NEWLINE:
                        self.stopped = f"no line break in the first {MAX_NO_NEWLINE:,} bytes after a word"
                        return
                    if len(line) > MAX_WORD:
                        continue  # part of an over-long line
                elif run:
                    run = 0
                    self.skipped += 1  # the end of an over-long line
                    continue
                word = line.rstrip(b"\r\n")
                if word:
                    yield word


def read_wordlist(path: str) -> Wordlist:
    return Wordlist(path)


@dataclass
class CrackResult:
    """What a dictionary attack found: the passphrase per stream, how many guesses, how fast."""

    derivation: str  # "sha256" or "qgc"
    found: dict[Stream, tuple[str, int]] = field(default_factory=dict)  # stream -> (passphrase, frame)
    guesses: int = 0
    seconds: float = 0.0

    @property
    def rate(self) -> float:
        return self.guesses / self.seconds if self.seconds > 0 else float("inf")

    @property
    def passphrase(self) -> str | None:
        """The first passphrase found (one-target use)."""
        return next((word for word, _ in self.found.values()), None)


def crack(targets: dict[Stream, list[Frame]], words: Iterable[bytes], derivation: str = "sha256",
          iterations: int = QGC_ITERATIONS) -> CrackResult:
    """Try each word as the passphrase of every unsolved stream, until every stream is solved."""
    result = CrackResult(derivation)
    pending = _candidates(targets)
    sha = hashlib.sha256
    t0 = time.perf_counter()
    for word in words:
        if not pending:
            break
        result.guesses += 1
        if derivation == "sha256":
            key = sha(word).digest()
        else:
            key = hashlib.pbkdf2_hmac("sha256", word, QGC_SALT, iterations, 32)
        base = sha(key)
        for s, c in list(pending.items()):
            record = _verifies(base, c)
            if record is not None:
                result.found[s] = (word.decode("utf-8", "backslashreplace"), record)
                del pending[s]
    result.seconds = time.perf_counter() - t0
    return result


def crack_sha256(raw: bytes, words: Iterable[bytes]) -> CrackResult:
    """Try SHA-256(word) as the signing key of the one signed frame `raw` (benchmarks)."""
    return _crack_raw(raw, words, "sha256", QGC_ITERATIONS)


def crack_qgc(raw: bytes, words: Iterable[bytes], iterations: int = QGC_ITERATIONS) -> CrackResult:
    """Try QGroundControl's PBKDF2-HMAC-SHA256 derivation of each word (slow by design)."""
    return _crack_raw(raw, words, "qgc", iterations)


class _Raw:
    """A stand-in target: only `raw` and `record` are read."""

    def __init__(self, raw: bytes) -> None:
        self.raw = raw
        self.record = 0


def _crack_raw(raw: bytes, words: Iterable[bytes], derivation: str, iterations: int) -> CrackResult:
    return crack({(0, 0, 0): [_Raw(raw)]}, words, derivation, iterations)  # type: ignore[list-item]


def passphrase_findings(targets: dict[Stream, list[Frame]], words: Iterable[bytes], qgc: bool) -> list[Finding]:
    """Findings of a dictionary attack on every signing stream's passphrase (SHA-256, then QGC's PBKDF2
    for the streams left when `qgc`; the wordlist is read once per derivation)."""
    if not targets:
        return [finding("passphrase-not-found", "no signed frame with a good CRC to test a wordlist on")]
    if qgc and not isinstance(words, Wordlist):
        words = list(words)  # a second derivation needs the words again (a Wordlist reads its file again)
    results = [crack(targets, words, "sha256")]
    left = {s: f for s, f in targets.items() if s not in results[0].found}
    if left and qgc:
        results.append(crack(left, words, "qgc"))
    speeds = "; ".join(f"{r.guesses} {'SHA-256' if r.derivation == 'sha256' else 'QGC PBKDF2'} guesses in "
                       f"{r.seconds:.3f} s ({r.rate:,.0f}/s)" for r in results)
    if isinstance(words, Wordlist) and (words.skipped or words.stopped):
        notes = [f"{words.skipped} over-long line(s) skipped"] if words.skipped else []
        notes += [f"reading stopped: {words.stopped}"] if words.stopped else []
        speeds += f"; wordlist: {'; '.join(notes)}"
    out: list[Finding] = []
    for r in results:
        how = ("SHA-256(passphrase), as MAVProxy and older QGroundControl" if r.derivation == "sha256"
               else "PBKDF2-HMAC-SHA256, 600000 iterations, as current QGroundControl")
        by_word: dict[str, list[Stream]] = {}
        for s, (word, _) in r.found.items():
            by_word.setdefault(word, []).append(s)
        for word, streams in by_word.items():
            records = [r.found[s][1] for s in streams]
            out.append(finding("weak-passphrase",
                               f"signing passphrase {word!r} is in the wordlist (key = {how}); it verifies "
                               f"{', '.join(_stream_text(s) for s in streams)} (frame "
                               f"{', '.join(map(str, records))}); {speeds}", records))
    unsolved = [s for s in targets if not any(s in r.found for r in results)]
    if unsolved:
        tried = "SHA-256" + (" and QGC PBKDF2" if qgc else "")
        records = [targets[s][0].record for s in unsolved]
        out.append(finding("passphrase-not-found",
                           f"no word of the wordlist ({results[0].guesses} words, {tried}) derives the signing key "
                           f"of {', '.join(_stream_text(s) for s in unsolved)} (frame "
                           f"{', '.join(map(str, records))}); {speeds}", records))
    return out
