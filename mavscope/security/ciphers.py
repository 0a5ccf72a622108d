"""Payload ciphers: SecureMAV's XOR and AES-128-CTR, and mavscope's authenticated `aes-gcm` profile.

SecureMAV restarts the AES-CTR counter for every frame, so every frame is XORed with the same
keystream: `FixedKeystream` computes it once (with `cryptography`) and XORs, which is exactly what
the scheme does and why one known plaintext reveals every other frame (audit `keystream-reuse`).

The `aes-gcm` profile (docs/security.md, "The aes-gcm profile"):

    payload on the wire = session_id (4) || counter (8, big-endian) || ciphertext || tag (16)
    nonce (96 bits)     = session_id || counter           (as DDS-Security: session id || IV suffix)
    AAD                 = the 10-byte MAVLink v2 header as sent (STX .. MSGID, LEN counts the above)
    session key         = HKDF-SHA256(master, salt="mavscope aes-gcm v1", info="session key" || session_id)
    plaintext           = the MAVLink payload with trailing zero bytes trimmed (at most 227 bytes)
"""

from __future__ import annotations

import struct
from typing import NamedTuple

from cryptography.exceptions import InvalidTag
from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.ciphers import Cipher, algorithms, modes
from cryptography.hazmat.primitives.ciphers.aead import AESGCM
from cryptography.hazmat.primitives.kdf.hkdf import HKDF

MAX_PAYLOAD = 255
GCM_SESSION_LEN = 4
GCM_COUNTER_LEN = 8
GCM_NONCE_LEN = GCM_SESSION_LEN + GCM_COUNTER_LEN
GCM_TAG_LEN = 16
GCM_OVERHEAD = GCM_NONCE_LEN + GCM_TAG_LEN  # 28 bytes: plaintext payloads up to 227 bytes
GCM_SALT = b"mavscope aes-gcm v1"
GCM_INFO = b"session key"


class CipherError(ValueError):
    """Decryption failed (wrong key, modified frame, malformed ciphertext). Carries no key material."""


def hkdf_sha256(ikm: bytes, salt: bytes, info: bytes, length: int = 32) -> bytes:
    return HKDF(algorithm=hashes.SHA256(), length=length, salt=salt, info=info).derive(ikm)


def xor_bytes(data: bytes, stream: bytes) -> bytes:
    """data XOR stream (stream at least as long as data)."""
    n = len(data)
    if not n:
        return b""
    return (int.from_bytes(data, "little") ^ int.from_bytes(stream[:n], "little")).to_bytes(n, "little")


class FixedKeystream:
    """A keystream that is the same for every frame: repeated XOR key bytes, or AES-CTR restarted."""

    __slots__ = ("stream",)

    def __init__(self, stream: bytes) -> None:
        self.stream = stream

    @classmethod
    def xor(cls, key: bytes) -> FixedKeystream:
        return cls((key * (MAX_PAYLOAD // len(key) + 1))[:MAX_PAYLOAD])

    @classmethod
    def aes_ctr(cls, key: bytes, iv: bytes) -> FixedKeystream:
        enc = Cipher(algorithms.AES(key), modes.CTR(iv)).encryptor()
        return cls(enc.update(b"\x00" * MAX_PAYLOAD) + enc.finalize())

    def apply(self, data: bytes) -> bytes:
        """Encrypt or decrypt (the same operation)."""
        return xor_bytes(data, self.stream)

    def __repr__(self) -> str:
        return "FixedKeystream(...)"


def gcm_session_key(master: bytes, session_id: int) -> bytes:
    return hkdf_sha256(master, GCM_SALT, GCM_INFO + session_id.to_bytes(4, "big"))


class GcmNonce(NamedTuple):
    session_id: int
    counter: int


def gcm_nonce(payload: bytes) -> GcmNonce:
    if len(payload) < GCM_OVERHEAD:
        raise CipherError(f"aes-gcm payload of {len(payload)} bytes is shorter than nonce and tag ({GCM_OVERHEAD})")
    session_id, counter = struct.unpack_from(">IQ", payload, 0)
    return GcmNonce(session_id, counter)


def gcm_seal(session_key: bytes, session_id: int, counter: int, header: bytes, plaintext: bytes) -> bytes:
    """The encrypted payload (nonce || ciphertext || tag) for a frame whose header is `header`."""
    if len(plaintext) + GCM_OVERHEAD > MAX_PAYLOAD:
        raise CipherError(f"aes-gcm plaintext of {len(plaintext)} bytes does not fit "
                          f"(at most {MAX_PAYLOAD - GCM_OVERHEAD})")
    nonce = struct.pack(">IQ", session_id, counter)
    return nonce + AESGCM(session_key).encrypt(nonce, plaintext, bytes(header))


def gcm_open(session_key: bytes, header: bytes, payload: bytes) -> bytes:
    """The plaintext of an aes-gcm payload; CipherError when the tag does not verify."""
    if len(payload) < GCM_OVERHEAD:
        raise CipherError(f"payload of {len(payload)} bytes is shorter than aes-gcm nonce and tag ({GCM_OVERHEAD})")
    nonce = payload[:GCM_NONCE_LEN]
    try:
        return AESGCM(session_key).decrypt(nonce, payload[GCM_NONCE_LEN:], bytes(header))
    except InvalidTag:
        raise CipherError("authentication tag does not verify (wrong key or modified frame)") from None
