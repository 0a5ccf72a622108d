"""The X25519 key exchange carried by MAVSCOPE_KEY_EXCHANGE (dissectors/mavscope.xml, docs/security.md).

Each side sends its public key with a key id; the receiver derives, per exchange,

    shared      = X25519(own private key, peer public key)
    salt        = "mavscope-kex-v1"
    info(label) = label || key_id (4 bytes, big-endian) || min(pub_a, pub_b) || max(pub_a, pub_b)
    signing key = HKDF-SHA256(shared, salt, info("mavscope signing key"), 32)
    aes-gcm key = HKDF-SHA256(shared, salt, info("mavscope aes-gcm key"), 32)   (the profile's master key)

Re-keying: a peer public key with a new key id opens epoch `key_id`; frames are verified with the
key of the newest epoch first (then older ones, so frames in flight across a re-key still verify; the
verifier tries at most `signing.CAPTURE_KEYS` keys that came from the capture on a new stream), and
the aes-gcm key is chosen by the nonce's session id, which is the epoch's key id.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple, cast

from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey, X25519PublicKey

from mavscope.security.ciphers import hkdf_sha256
from mavscope.security.keys import SigningKey

KEY_EXCHANGE_MSGID = 65100
KEX_SALT = b"mavscope-kex-v1"
LABEL_SIGNING = b"mavscope signing key"
LABEL_AES_GCM = b"mavscope aes-gcm key"


def public_key(private: bytes) -> bytes:
    from cryptography.hazmat.primitives import serialization

    return X25519PrivateKey.from_private_bytes(private).public_key().public_bytes(
        serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def derive_epoch_keys(shared: bytes, key_id: int, pub_a: bytes, pub_b: bytes) -> tuple[bytes, bytes]:
    """(signing key, aes-gcm master key) of the exchange `key_id` between public keys a and b."""
    lo, hi = sorted((bytes(pub_a), bytes(pub_b)))
    tail = key_id.to_bytes(4, "big") + lo + hi
    return (hkdf_sha256(shared, KEX_SALT, LABEL_SIGNING + tail), hkdf_sha256(shared, KEX_SALT, LABEL_AES_GCM + tail))


class Epoch(NamedTuple):
    key_id: int
    signing: SigningKey
    gcm_master: bytes
    peer: tuple[int, int]  # (sysid, compid) that sent the peer public key
    record: int  # capture record of the exchange message


class KeyExchangeTracker:
    """Reads MAVSCOPE_KEY_EXCHANGE messages and derives the keys of each epoch it can."""

    def __init__(self, private_keys: list[bytes]) -> None:
        self.own = {public_key(p): p for p in private_keys}
        self.epochs: dict[int, Epoch] = {}
        self.seen: set[tuple[int, bytes]] = set()
        self._private: X25519PrivateKey | None = None  # the first own key, parsed once

    def observe(self, fields: dict[str, object], sysid: int, compid: int, record: int) -> tuple[Epoch | None, str]:
        """Handle one exchange message: (the new epoch or None, a description for the note)."""
        key_id = int(cast(int, fields.get("key_id", 0)))  # uint32_t
        key_bytes = cast("Iterable[int]", fields.get("public_key", ()))  # uint8_t[32]: a list of ints
        pub = bytes(int(b) & 0xFF for b in key_bytes)
        if len(pub) != 32:
            return None, f"key exchange {key_id}: public key of {len(pub)} bytes"
        if pub in self.own:
            return None, f"key exchange {key_id}: own public key"
        if (key_id, pub) in self.seen:
            return None, f"key exchange {key_id}: peer public key repeated"
        self.seen.add((key_id, pub))
        if not self.own:
            return None, f"key exchange {key_id}: peer public key (no --ecdh-private to derive the keys)"
        if key_id in self.epochs:
            return None, f"key exchange {key_id}: a second peer key for an existing key id (ignored)"
        own_pub, own_priv = next(iter(self.own.items()))
        if self._private is None:
            self._private = X25519PrivateKey.from_private_bytes(own_priv)
        try:
            shared = self._private.exchange(X25519PublicKey.from_public_bytes(pub))
        except ValueError:  # an all-zero or other low-order point: X25519 gives the all-zero secret
            return None, (f"key exchange {key_id}: peer public key is a low-order point (all-zero shared secret): "
                          "no keys derived; a peer sending it forces a predictable key")
        signing, gcm = derive_epoch_keys(shared, key_id, own_pub, pub)
        epoch = Epoch(key_id, SigningKey(f"ecdh-{key_id}", signing), gcm, (sysid, compid), record)
        self.epochs[key_id] = epoch
        return epoch, f"key exchange {key_id}: keys derived (signing key ecdh-{key_id})"
