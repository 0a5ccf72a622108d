"""Dictionary attacks on the signing passphrase: SHA-256 (MAVProxy, older QGroundControl) and
QGroundControl's PBKDF2 derivation, tried against a signed frame of the capture (`audit --wordlist`).

The one finding that prints a secret is `weak-passphrase`: reporting the passphrase a dictionary found
is the point of this audit (docs/security.md).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Iterable
from dataclasses import dataclass
from hmac import compare_digest

from mavscope.mavlink.frame import CrcStatus, Frame
from mavscope.notes import Finding, finding
from mavscope.security.keys import QGC_ITERATIONS, QGC_SALT


@dataclass(frozen=True)
class CrackResult:
    passphrase: str | None
    derivation: str  # "sha256" or "qgc"
    guesses: int
    seconds: float

    @property
    def rate(self) -> float:
        return self.guesses / self.seconds if self.seconds > 0 else float("inf")


def crack_sha256(raw: bytes, words: Iterable[bytes]) -> CrackResult:
    """Try SHA-256(word) as the signing key of the signed frame `raw`."""
    data, value = raw[:-6], raw[-6:]
    sha = hashlib.sha256
    n = 0
    t0 = time.perf_counter()
    for word in words:
        n += 1
        if compare_digest(sha(sha(word).digest() + data).digest()[:6], value):
            return CrackResult(word.decode("utf-8", "replace"), "sha256", n, time.perf_counter() - t0)
    return CrackResult(None, "sha256", n, time.perf_counter() - t0)


def crack_qgc(raw: bytes, words: Iterable[bytes], iterations: int = QGC_ITERATIONS) -> CrackResult:
    """Try QGroundControl's PBKDF2-HMAC-SHA256 derivation of each word (slow by design)."""
    data, value = raw[:-6], raw[-6:]
    n = 0
    t0 = time.perf_counter()
    for word in words:
        n += 1
        key = hashlib.pbkdf2_hmac("sha256", word, QGC_SALT, iterations, 32)
        if compare_digest(hashlib.sha256(key + data).digest()[:6], value):
            return CrackResult(word.decode("utf-8", "replace"), "qgc", n, time.perf_counter() - t0)
    return CrackResult(None, "qgc", n, time.perf_counter() - t0)


def read_wordlist(path: str) -> list[bytes]:
    with open(path, "rb") as fh:
        return [w for w in (line.rstrip(b"\r\n") for line in fh) if w]


def passphrase_findings(frames: list[Frame], words: list[bytes], qgc: bool) -> list[Finding]:
    target = next((f for f in frames if f.signature is not None and f.crc_status is CrcStatus.OK), None)
    if target is None:
        return [finding("passphrase-not-found", "no signed frame with a good CRC to test a wordlist on")]
    results = [crack_sha256(target.raw, words)]
    if results[0].passphrase is None and qgc:
        results.append(crack_qgc(target.raw, words))
    speeds = "; ".join(f"{r.guesses} {'SHA-256' if r.derivation == 'sha256' else 'QGC PBKDF2'} guesses in "
                       f"{r.seconds:.3f} s ({r.rate:,.0f}/s)" for r in results)
    found = results[-1]
    if found.passphrase is not None:
        how = ("SHA-256(passphrase), as MAVProxy and older QGroundControl" if found.derivation == "sha256"
               else "PBKDF2-HMAC-SHA256, 600000 iterations, as current QGroundControl")
        return [finding("weak-passphrase",
                        f"signing passphrase {found.passphrase!r} is in the wordlist (key = {how}); it verifies "
                        f"frame {target.record}; {speeds}", (target.record,))]
    tried = "SHA-256" + (" and QGC PBKDF2" if qgc else "")
    return [finding("passphrase-not-found",
                    f"no word of the wordlist ({len(words)} words, {tried}) derives the signing key of frame "
                    f"{target.record}; {speeds}", (target.record,))]
