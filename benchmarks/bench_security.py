#!/usr/bin/env python3
"""Security micro-benchmarks: verified signed frames per second, wordlist guesses per second.

    python benchmarks/bench_security.py [--frames N] [--qgc-words N]

Signature verification runs `SignatureVerifier.verify` (the stage's hot path: MAC with a cached
`hashlib.sha256(key)` copied per frame, `hmac.compare_digest`, replay state) over N distinct frames signed
by pymavlink, with 1 key and with 4 keys (the right one last: the per-stream memory makes it first
after one frame). Guesses: SHA-256 passphrase derivation (`crack_sha256`) and QGroundControl's PBKDF2
(600000 iterations, `crack_qgc`) against one signed frame, with a wordlist that does not contain it.
Hostile key exchanges: `mavscope verify --ecdh-private` of a raw capture of N MAVSCOPE_KEY_EXCHANGE
frames (random public keys, key ids 1..N) each followed by a HEARTBEAT signed with a random key (a forged
frame: every key the capture gave is a candidate), wall clock of the whole command.
"""

from __future__ import annotations

import argparse
import hashlib
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pymavlink.dialects.v20 import common as v2  # noqa: E402

from mavscope.security.keys import SigningKey  # noqa: E402
from mavscope.security.passphrase import crack_qgc, crack_sha256  # noqa: E402
from mavscope.security.signing import SignatureVerifier  # noqa: E402
from scripts.capgen.encode import encode_frame  # noqa: E402
from scripts.capgen.kex import KEY_EXCHANGE_MSGID, key_exchange_crc_extra, key_exchange_payload  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
HEARTBEAT = bytes.fromhex("00000000020300040302")  # custom_mode, type, autopilot, base_mode, status, version


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


def bench_exchanges(n: int) -> float:
    """Seconds `mavscope verify --ecdh-private` takes over n key exchanges and n forged signed frames."""
    rnd = random.Random(1)
    extra = key_exchange_crc_extra(ROOT / "dissectors" / "mavscope.xml")
    frames = []
    for i in range(1, n + 1):
        frames.append(encode_frame(KEY_EXCHANGE_MSGID, key_exchange_payload(i, i, 1, 1, rnd.randbytes(32)), extra,
                                   sysid=1 + i % 250, seq=i & 255))
        frames.append(encode_frame(0, HEARTBEAT, 50, sysid=1 + i % 250, seq=i & 255, signing_key=rnd.randbytes(32),
                                   link_id=rnd.randrange(256), timestamp=rnd.randrange(1 << 48)))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "kex.raw"
        path.write_bytes(b"".join(frames))
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "mavscope", "verify", str(path), "--ecdh-private", "hex:" + "11" * 32],
                       stdout=subprocess.DEVNULL, cwd=ROOT, check=False)
        return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=300_000)
    ap.add_argument("--words", type=int, default=300_000)
    ap.add_argument("--qgc-words", type=int, default=5)
    ap.add_argument("--exchanges", type=int, default=10_000)
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
    if a.exchanges:
        seconds = bench_exchanges(a.exchanges)
        print(f"verify, {a.exchanges} key exchanges + {a.exchanges} forged frames: {seconds:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
