"""Keys the capture gives (key exchanges under --ecdh-private, SETUP_SIGNING under --use-leaked-keys) are
tried at most CAPTURE_KEYS at a time (stop 25).

A frame its stream's key does not verify is tried with every key. Each key exchange used to add one for
good, so a capture of n exchanges and n forged signed frames cost n * n MACs: 10,000 of each took
`verify` 30 s, 100,000 of each would take about an hour (now 1.5 s and 10.2 s). The expected keys here come from
scripts/capgen/kex.py (the exchange written from its specification with `cryptography`) and pymavlink's
signer, not from mavscope.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from mavscope.mavlink.frame import SignatureReason, SignatureStatus
from mavscope.security.keys import SigningKey
from mavscope.security.signing import CAPTURE_KEYS, SignatureVerifier
from scripts.capgen.encode import encode_frame
from scripts.capgen.kex import (
    KEY_EXCHANGE_MSGID,
    epoch_keys,
    key_exchange_crc_extra,
    key_exchange_payload,
    public_key,
    shared_secret,
)
from tests.conftest import ROOT, Cli
from tests.support.security import EPOCH_2026, heartbeat, signer, statuses, write_raw

HEARTBEAT = bytes.fromhex("00000000" "02" "03" "00" "04" "03")  # custom_mode, type, autopilot, base_mode, status
HEARTBEAT_EXTRA = 50  # CRC_EXTRA of HEARTBEAT (common.xml)


def key(n: int) -> SigningKey:
    return SigningKey(f"k{n}", hashlib.sha256(b"%d" % n).digest())


def signed(k: SigningKey, link_id: int, timestamp: int) -> bytes:
    return encode_frame(0, HEARTBEAT, HEARTBEAT_EXTRA, sysid=1, compid=1, signing_key=k.secret, link_id=link_id,
                        timestamp=timestamp)


def verdict(v: SignatureVerifier, k: SigningKey, link_id: int, timestamp: int) -> tuple[SignatureStatus, str | None]:
    raw = signed(k, link_id, timestamp)
    got = v.verify(raw, 1, 1, link_id, timestamp, None, 0.0)
    return got.status, None if got.key is None else got.key.name


def test_the_keys_tried_stay_bounded_and_the_streams_keep_theirs() -> None:
    user = key(0)
    v = SignatureVerifier([user])
    first = key(1)
    assert v.add_key(first, first=True, from_capture=True) is None
    assert verdict(v, first, 7, 100) == (SignatureStatus.VALID, "k1")  # stream 7 is first's
    retired = [v.add_key(key(n), first=True, from_capture=True) for n in range(2, 3 * CAPTURE_KEYS + 1)]
    assert len(v.keys) == CAPTURE_KEYS + 1  # the user's key is never put out
    assert [r.name for r in retired if r is not None] == [f"k{n}" for n in range(1, 2 * CAPTURE_KEYS + 1)]
    assert verdict(v, user, 1, 100) == (SignatureStatus.VALID, "k0")
    assert verdict(v, key(3 * CAPTURE_KEYS), 2, 100) == (SignatureStatus.VALID, f"k{3 * CAPTURE_KEYS}")
    assert verdict(v, key(2 * CAPTURE_KEYS + 1), 3, 100)[0] is SignatureStatus.VALID  # the oldest still tried
    assert verdict(v, first, 7, 101) == (SignatureStatus.VALID, "k1")  # its stream keeps it
    got = v.verify(signed(first, 8, 100), 1, 1, 8, 100, None, 0.0)  # a new stream: not tried any more
    assert (got.status, got.reason) == (SignatureStatus.INVALID, SignatureReason.NO_KEY_MATCHES)


def test_the_key_put_out_is_the_one_that_least_recently_verified_a_new_stream() -> None:
    v = SignatureVerifier()
    keys = [key(n) for n in range(CAPTURE_KEYS)]
    for k in keys:
        v.add_key(k, from_capture=True)
    assert verdict(v, keys[0], 1, 100)[0] is SignatureStatus.VALID  # keys[0] verified the newest stream
    assert v.add_key(key(CAPTURE_KEYS), from_capture=True) is keys[1]
    assert v.add_key(key(CAPTURE_KEYS + 1), from_capture=True) is keys[2]
    assert v.add_key(keys[5], from_capture=True) is None  # already tried: nothing changes
    assert len(v.keys) == CAPTURE_KEYS and keys[0] in v.keys


def test_many_key_exchanges_keep_the_newest_epochs_and_say_which_key_left(cli: Cli, tmp_path: Path) -> None:
    """CAPTURE_KEYS + 2 exchanges from the vehicle, then HEARTBEATs on new streams signed with the keys
    of epochs 1, 2, 3 and the newest: epochs 1 and 2 are no longer tried."""
    own, peer = b"\x11" * 32, b"\x22" * 32
    own_pub, peer_pub = public_key(own), public_key(peer)
    shared = shared_secret(peer, own_pub)
    extra = key_exchange_crc_extra(ROOT / "dissectors" / "mavscope.xml")
    epochs = CAPTURE_KEYS + 2
    frames = [encode_frame(KEY_EXCHANGE_MSGID, key_exchange_payload(n, n, 255, 190, peer_pub), extra, sysid=1,
                           compid=1) for n in range(1, epochs + 1)]
    signing = {n: epoch_keys(shared, n, own_pub, peer_pub)[0] for n in (1, 2, 3, epochs)}
    for link, n in enumerate((1, 2, 3, epochs), 1):
        frames.append(bytes(heartbeat(signer(signing[n], sysid=1, compid=1, link_id=link, timestamp=EPOCH_2026))))
    rows = cli.jsonl(write_raw(tmp_path, frames), "--ecdh-private", "hex:" + own.hex())
    assert statuses(rows[epochs:]) == ["invalid", "invalid", "valid", "valid"]
    assert rows[-1]["signature"]["key"] == f"ecdh-{epochs}" and rows[-2]["signature"]["key"] == "ecdh-3"
    said = [n["message"] for r in rows[:epochs] for n in r["notes"] if "no longer tried" in n["message"]]
    assert [s.split("; key ")[1].split()[0] for s in said] == ["ecdh-1", "ecdh-2"]
    assert all(own.hex() not in s and signing[1].hex() not in s for s in said)


def test_many_leaked_keys_keep_the_newest(cli: Cli, tmp_path: Path) -> None:
    """CAPTURE_KEYS + 1 SETUP_SIGNING frames (pymavlink), each leaking another key, then HEARTBEATs on new
    streams signed with the first and the last leaked key: the first is no longer tried."""
    leaked = [hashlib.sha256(b"leak %d" % n).digest() for n in range(CAPTURE_KEYS + 1)]
    gcs = signer(None)
    frames = [bytes(gcs.setup_signing_encode(1, 1, k, EPOCH_2026).pack(gcs)) for k in leaked]
    for link, k in enumerate((leaked[0], leaked[-1]), 1):
        frames.append(bytes(heartbeat(signer(k, sysid=1, compid=1, link_id=link, timestamp=EPOCH_2026 + 5))))
    rows = cli.jsonl(write_raw(tmp_path, frames), "--use-leaked-keys")
    assert statuses(rows[-2:]) == ["invalid", "valid"]
    assert rows[-1]["signature"]["key"] == f"leaked-{CAPTURE_KEYS + 1}"
    said = [n["message"] for r in rows for n in r["notes"] if "no longer tried" in n["message"]]
    assert len(said) == 1 and "key leaked-1 is no longer tried" in said[0]
