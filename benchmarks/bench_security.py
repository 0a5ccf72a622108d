#!/usr/bin/env python3
"""Security micro-benchmarks: verified signed frames per second, wordlist guesses per second.

    python benchmarks/bench_security.py [--frames N] [--qgc-words N]

Signature verification runs `SignatureVerifier.verify` (the stage's hot path: MAC with a cached
`hashlib.sha256(key)` copied per frame, `hmac.compare_digest`, replay state) over N distinct frames signed
by pymavlink, with 1 key and with 4 keys (the right one last: the per-stream memory makes it first
after one frame). Guesses: SHA-256 passphrase derivation (`crack_sha256`) and QGroundControl's PBKDF2
(600000 iterations, `crack_qgc`) against one signed frame, with a wordlist that does not contain it.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pymavlink.dialects.v20 import common as v2  # noqa: E402

from mavscope.security.keys import SigningKey  # noqa: E402
from mavscope.security.passphrase import crack_qgc, crack_sha256  # noqa: E402
from mavscope.security.signing import SignatureVerifier  # noqa: E402


def signed_frames(n: int, key: bytes) -> list[bytes]:
    mav = v2.MAVLink(None, srcSystem=1, srcComponent=1)
    mav.signing.secret_key, mav.signing.link_id, mav.signing.sign_outgoing = key, 0, True
    mav.signing.timestamp = 35_341_200_000_000
    return [bytes(mav.attitude_encode(i, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0).pack(mav)) for i in range(n)]


def bench_verify(frames: list[bytes], keys: list[SigningKey]) -> float:
    v = SignatureVerifier(keys)
    verify = v.verify
    t0 = time.perf_counter()
    for raw in frames:
        ts = int.from_bytes(raw[-12:-6], "little")
        verdict = verify(raw, 1, 1, 0, ts, None, 0.0)
    dt = time.perf_counter() - t0
    assert verdict.status.value == "valid"
    return len(frames) / dt


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=300_000)
    ap.add_argument("--words", type=int, default=300_000)
    ap.add_argument("--qgc-words", type=int, default=5)
    a = ap.parse_args()
    key = hashlib.sha256(b"bench").digest()
    frames = signed_frames(a.frames, key)
    right = SigningKey("right", key)
    decoys = [SigningKey(f"decoy{i}", bytes([i]) * 32) for i in range(3)]
    one = max(bench_verify(frames, [right]) for _ in range(3))
    four = max(bench_verify(frames, decoys + [right]) for _ in range(3))
    print(f"signature verification, 1 key:  {one:12,.0f} frames/s ({a.frames} frames, best of 3)")
    print(f"signature verification, 4 keys: {four:12,.0f} frames/s (right key last)")
    words = [f"not-it-{i}".encode() for i in range(a.words)]
    r = crack_sha256(frames[0], words)
    print(f"wordlist, SHA-256:             {r.rate:12,.0f} guesses/s ({r.guesses} words)")
    r = crack_qgc(frames[0], words[: a.qgc_words])
    print(f"wordlist, QGC PBKDF2 600000:   {r.rate:12,.2f} guesses/s ({r.guesses} words)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
