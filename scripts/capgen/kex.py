"""mavscope's X25519 key exchange, written from its specification (docs/security.md, "Key exchange";
the MAVSCOPE_KEY_EXCHANGE message in dissectors/mavscope.xml) with `cryptography`, not taken from
mavscope: the capture built with it is what mavscope's key-exchange support is tested against.

For epoch N with public keys A and B:
    shared       = X25519(own private key, peer public key)
    tail         = N (4 bytes, big-endian) || min(A, B) || max(A, B)
    signing key  = HKDF-SHA256(shared, salt "mavscope-kex-v1", info "mavscope signing key" || tail, 32)
    aes-gcm key  = HKDF-SHA256(shared, salt "mavscope-kex-v1", info "mavscope aes-gcm key" || tail, 32)
"""

from __future__ import annotations

import struct
from pathlib import Path

from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric.x25519 import X25519PrivateKey, X25519PublicKey
from cryptography.hazmat.primitives.kdf.hkdf import HKDF
from pymavlink.generator import mavparse

KEY_EXCHANGE_MSGID = 65_100  # MAVSCOPE_KEY_EXCHANGE
KEX_SALT = b"mavscope-kex-v1"
SIGNING_INFO = b"mavscope signing key"
AES_GCM_INFO = b"mavscope aes-gcm key"
# Wire order (MAVLink sorts fields by type size, largest first): timestamp uint64, key_id uint32,
# target_system uint8, target_component uint8, public_key uint8[32].
KEY_EXCHANGE_LAYOUT = struct.Struct("<QIBB32s")


def public_key(private: bytes) -> bytes:
    """The 32-byte X25519 public key (RFC 7748 u-coordinate) of a 32-byte private key."""
    return X25519PrivateKey.from_private_bytes(private).public_key().public_bytes(
        serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def shared_secret(private: bytes, peer_public: bytes) -> bytes:
    """X25519(own private key, peer public key)."""
    return X25519PrivateKey.from_private_bytes(private).exchange(X25519PublicKey.from_public_bytes(peer_public))


def epoch_keys(shared: bytes, key_id: int, public_a: bytes, public_b: bytes) -> tuple[bytes, bytes]:
    """(signing key, aes-gcm master key) of epoch `key_id`. The public keys enter in byte-wise order, so
    both sides derive the same keys whichever is "A"."""
    low, high = sorted((public_a, public_b))
    tail = key_id.to_bytes(4, "big") + low + high

    def hkdf(info: bytes) -> bytes:
        return HKDF(algorithm=hashes.SHA256(), length=32, salt=KEX_SALT, info=info + tail).derive(shared)

    return hkdf(SIGNING_INFO), hkdf(AES_GCM_INFO)


def key_exchange_payload(timestamp_us: int, key_id: int, target_system: int, target_component: int,
                         public: bytes) -> bytes:
    """The MAVSCOPE_KEY_EXCHANGE payload in wire order (untrimmed: the encoder trims it)."""
    return KEY_EXCHANGE_LAYOUT.pack(timestamp_us, key_id, target_system, target_component, public)


def key_exchange_crc_extra(dialect_xml: Path) -> int:
    """CRC_EXTRA of MAVSCOPE_KEY_EXCHANGE as pymavlink's XML parser computes it from the dialect file,
    so that a change to the message definition cannot leave the captures behind silently."""
    xml = mavparse.MAVXML(str(dialect_xml), mavparse.PROTOCOL_2_0)
    return next(m.crc_extra for m in xml.message if m.id == KEY_EXCHANGE_MSGID)
