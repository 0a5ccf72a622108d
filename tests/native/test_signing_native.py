"""The native signing code on its own: SHA-256, the skew's round(x, 6), and the SigningState store.

- `_native.sha256` (src/mavscope_native/sha256.c, fed in uneven pieces) against the FIPS 180-2 appendix B
  digests (written out here from the standard) and against hashlib on random inputs of every length
  around the block boundaries.
- `_native.format_skew(x)` against `orjson.dumps(round(x, 6))`, what the pure path writes for a skew.
- `_native.SigningState` and `DictSigningStore` (mavscope/security/signing.py) give the same answers to the
  same calls; the native one never shows key material (repr, errors, pickling, copying).
"""

from __future__ import annotations

import copy
import hashlib
import math
import pickle
import random
import struct

import orjson
import pytest

from mavscope.security.signing import DictSigningStore

native = pytest.importorskip("mavscope._native", reason="the native extension is not built (no compiler at install)")

# FIPS 180-2, appendix B (SHA-256 examples): the message and its digest as the standard prints them
FIPS_VECTORS = [
    (b"abc", "ba7816bf 8f01cfea 414140de 5dae2223 b00361a3 96177a9c b410ff61 f20015ad"),
    (b"abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq",
     "248d6a61 d20638b8 e5c02693 0c3e6039 a33ce459 64ff2167 f6ecedd4 19db06c1"),
    (b"a" * 1_000_000, "cdc76e5c 9914fb92 81a1c7e2 84d73e67 f1809a48 a497200e 046d39cc c7112cd0"),
]


@pytest.mark.parametrize(("message", "digest"), FIPS_VECTORS, ids=["one-block", "two-block", "million-a"])
def test_sha256_fips_vectors(message: bytes, digest: str) -> None:
    assert native.sha256(message).hex() == digest.replace(" ", "")


def test_sha256_equals_hashlib() -> None:
    rng = random.Random(180_4)
    lengths = list(range(0, 300)) + [rng.randrange(300, 70_000) for _ in range(200)]
    for n in lengths:
        data = rng.randbytes(n)
        assert native.sha256(data) == hashlib.sha256(data).digest(), n
    # a MAVLink MAC's input: a 32-byte secret, then a whole signed frame but its last 6 bytes (25..292)
    for n in range(25, 293):
        data = rng.randbytes(32 + n)
        assert native.sha256(data) == hashlib.sha256(data).digest(), n


def skew_json(x: float) -> bytes:
    return orjson.dumps(round(x, 6))  # what the pure path writes (registry `_sig_skew`, orjson)


def doubles(rng: random.Random) -> list[float]:
    out = [0.0, -0.0, 1e-7, -1e-7, 5e-7, -5e-7, 4.9999999e-7, 0.5, 2.0**33, -(2.0**33), 2.0**33 - 2.0**-19,
           math.nextafter(2.0**33, 0.0), math.inf, -math.inf, 5e-324, -5e-324, 1.7976931348623157e308]
    out += [k / 128 for k in range(-2001, 2002, 2)]  # exact decimal ties at the 7th place: even digit wins
    out += [k / 2**20 + j for k in range(1, 2**20, 9_973) for j in (0, 1_000, 277_129_600)]
    for _ in range(100_000):
        out.append(rng.uniform(-100, 100))
        out.append(rng.uniform(-3e9, 3e9))
        out.append(rng.uniform(-1, 1) * 10.0 ** rng.randint(-12, 12))
        out.append(struct.unpack("<d", rng.randbytes(8))[0])
    for x in list(out[:50_000]):  # and the neighbours of 6-decimal values
        r = round(x, 6)
        if math.isfinite(r):
            out += [math.nextafter(r, math.inf), math.nextafter(r, -math.inf), r + 5e-7, r - 5e-7]
    return out


def test_skew_is_rounded_and_written_as_python_does() -> None:
    rng = random.Random(6)
    for x in doubles(rng):
        if math.isnan(x):
            continue  # orjson: null; Python's round(nan, 6) is nan too, checked below
        assert native.format_skew(x) == skew_json(x), repr(x)
    assert native.format_skew(math.nan) == b"null" == skew_json(math.nan)


def test_skew_of_the_signature_and_capture_times_of_real_frames() -> None:
    """Skews as the frames make them: SIGNING_EPOCH + timestamp / 100000 - capture time."""
    rng = random.Random(7)
    for _ in range(100_000):
        t = rng.uniform(1.4e9, 1.9e9) if rng.random() < 0.9 else rng.uniform(0, 2**33)
        ts = rng.randrange(2**48) if rng.random() < 0.2 else max(0, int((t - 1_420_070_400) * 100_000)
                                                                     + rng.randint(-10**7, 10**7))
        x = (1_420_070_400 + ts / 100_000) - t
        assert native.format_skew(x) == skew_json(x), (ts, t)


SECRET = bytes(range(32))


def test_signing_state_and_dict_store_answer_alike() -> None:
    rng = random.Random(12)
    stores = [native.SigningState(), DictSigningStore()]
    for s in stores:  # 10 keys: the key table grows twice
        assert [s.add_key(rng.randbytes(32), f"k{i}") for i in range(10)] == list(range(10))
    streams = [(rng.randrange(256), rng.randrange(256), rng.randrange(256)) for _ in range(3000)]
    for _ in range(20_000):
        stream = rng.choice(streams)
        if rng.random() < 0.5:
            last, key = rng.randrange(2**48), rng.randrange(10)
            for s in stores:
                s.put(stream, last, key)
        got = [s.get(stream) for s in stores]
        assert got[0] == got[1]
        assert len(stores[0]) == len(stores[1])
    for s in stores:
        with pytest.raises(ValueError, match="key slot"):
            s.put((1, 1, 0), 5, 10)  # no key slot 10


def test_signing_state_holds_every_stream() -> None:
    """Growth of the stream table: 2^17 streams, each found with its own values afterwards."""
    s = native.SigningState()
    s.add_key(SECRET, "key1")
    streams = [(i >> 16, (i >> 8) & 255, i & 255) for i in range(0, 1 << 24, 128)]
    for i, st in enumerate(streams):
        s.put(st, i, 0)
    assert len(s) == len(streams)
    assert all(s.get(st) == (i, 0) for i, st in enumerate(streams))
    assert s.get((0, 0, 1)) is None


def test_signing_state_never_shows_the_key() -> None:
    secret = bytes.fromhex("ac2193ecb3be4d7e444e2867d430a8b1618cd2ac1ed9710d580a79630f5420f0")
    s = native.SigningState()
    s.add_key(secret, "vehicle")
    s.put((1, 1, 0), 42, 0)
    texts = [repr(s), str(s), str(dir(s))]
    for attempt in (lambda: pickle.dumps(s), lambda: copy.copy(s), lambda: copy.deepcopy(s),
                    lambda: s.add_key(secret[:31], "short"), lambda: s.add_key(secret + b"\0", "long"),
                    lambda: s.put((1, 1, 256), 1, 0), lambda: s.put((1, 1, 0), -1, 0)):
        with pytest.raises((TypeError, ValueError, OverflowError)) as info:
            attempt()
        texts.append(str(info.value))
    assert repr(s) == "SigningState(1 keys, 1 streams)"
    for text in texts:
        assert secret.hex() not in text and secret.hex().upper() not in text
        assert str(list(secret[:8]))[1:-1] not in text and repr(secret)[2:-1] not in text
    assert not any(n in dir(s) for n in ("secret", "keys", "key", "_secret"))


def test_signing_state_accepts_long_and_odd_names() -> None:
    """A name the walker cannot write (too long as JSON, not UTF-8) still gets its slot: its frames are
    written by Python (the walk tests check the output)."""
    s = native.SigningState()
    assert s.add_key(SECRET, "n" * 5000) == 0
    assert s.add_key(SECRET, "\udcff") == 1
    assert s.add_key(SECRET, "\u00e9\"\\\n") == 2
    s.put((1, 1, 0), 1, 2)
    assert s.get((1, 1, 0)) == (1, 2)
