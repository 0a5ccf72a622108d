"""MAVLink 2 frames with encrypted payloads and signatures, written from the specifications (the MAVLink
2 serialization and signing pages; SecureMAV and the aes-gcm profile in docs/security.md) with hashlib
and `cryptography` only.

This is deliberately not mavscope's code: the captures and the security tests judge mavscope's
decoder, and an encoder shared with it would make the same mistakes in both directions and hide them.
It imports nothing of the generator either, so the tests can import it alone.

Order of operations, as SecureMAV does it: trim the plaintext payload, encrypt it, then compute the CRC
and the signature over the frame as sent (the ciphertext).
"""

from __future__ import annotations

import hashlib
import struct

from cryptography.hazmat.primitives import hashes
from cryptography.hazmat.primitives.ciphers import Cipher, algorithms, modes
from cryptography.hazmat.primitives.ciphers.aead import AESGCM
from cryptography.hazmat.primitives.kdf.hkdf import HKDF

STX_V2 = 0xFD
INCOMPAT_SIGNED = 0x01
METHOD_SHIFT = 5  # the cipher method sits in incompat flag bits 5-7
SCHEMES = ("xor", "aes-128-ctr", "aes-gcm")
GCM_SALT = b"mavscope aes-gcm v1"
GCM_INFO = b"session key"
GCM_TAG_LEN = 16
GCM_OVERHEAD = 4 + 8 + GCM_TAG_LEN  # session id, counter, tag


def x25_crc(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/MCRF4XX as MAVLink defines it (the X.25 CRC without the final XOR), byte by byte."""
    for byte in data:
        tmp = (byte ^ crc) & 0xFF
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc


def trim(payload: bytes) -> bytes:
    """MAVLink 2 drops trailing zero bytes of a payload, but always sends the first byte."""
    end = len(payload)
    while end > 1 and payload[end - 1] == 0:
        end -= 1
    return payload[:end]


def header_v2(length: int, incompat: int, seq: int, sysid: int, compid: int, msgid: int, compat: int = 0) -> bytes:
    """The 10-byte MAVLink 2 header: STX, LEN, INCOMPAT, COMPAT, SEQ, SYSID, COMPID, MSGID (24 bits, LE)."""
    return struct.pack("<BBBBBBBHB", STX_V2, length, incompat, compat, seq, sysid, compid,
                       msgid & 0xFFFF, msgid >> 16)


def signature_block(secret: bytes, signed_part: bytes, link_id: int, timestamp: int) -> bytes:
    """link id, 48-bit timestamp (units of 10 µs since 2015-01-01), and the first 6 bytes of
    SHA-256(secret || header || payload || CRC || link id || timestamp)."""
    tail = bytes([link_id]) + timestamp.to_bytes(6, "little")
    return tail + hashlib.sha256(secret + signed_part + tail).digest()[:6]


def xor_cipher(key: bytes, data: bytes) -> bytes:
    """SecureMAV's XOR scheme: the key bytes repeated over the payload (method 7 is XOR 0xAB)."""
    if not key:
        raise ValueError("xor needs a key of at least one byte")
    return bytes(b ^ key[i % len(key)] for i, b in enumerate(data))


def aes_128_ctr(key: bytes, iv: bytes, data: bytes) -> bytes:
    """SecureMAV's AES-128-CTR: the counter block restarts at the IV for every frame (a fixed keystream:
    that is SecureMAV's weakness, which mavscope's audit finds)."""
    if len(key) != 16 or len(iv) != 16:
        raise ValueError("aes-128-ctr needs a 16-byte key and a 16-byte IV")
    encryptor = Cipher(algorithms.AES(key), modes.CTR(iv)).encryptor()
    return encryptor.update(data) + encryptor.finalize()


def gcm_session_key(master: bytes, session_id: int) -> bytes:
    """K = HKDF-SHA256(IKM = master, salt = "mavscope aes-gcm v1", info = "session key" || S (4 bytes, BE),
    32 bytes): AES-256 whatever the master key's size."""
    if len(master) not in (16, 32):
        raise ValueError("the aes-gcm master key is 16 or 32 bytes")
    info = GCM_INFO + session_id.to_bytes(4, "big")
    return HKDF(algorithm=hashes.SHA256(), length=32, salt=GCM_SALT, info=info).derive(master)


def aes_gcm_payload(master: bytes, session_id: int, counter: int, plaintext: bytes, header: bytes) -> bytes:
    """The aes-gcm profile's wire payload: S || C || ciphertext || tag, nonce S || C, the header as
    associated data (so that changing any header byte fails the tag)."""
    nonce = session_id.to_bytes(4, "big") + counter.to_bytes(8, "big")
    return nonce + AESGCM(gcm_session_key(master, session_id)).encrypt(nonce, plaintext, header)


def encode_frame(msgid: int, payload: bytes, crc_extra: int, *, seq: int = 0, sysid: int = 1, compid: int = 1,
                 method: int = 0, scheme: str | None = None, key: bytes = b"", iv: bytes = b"\x00" * 16,
                 session_id: int = 0, counter: int = 0, signing_key: bytes | None = None, link_id: int = 0,
                 timestamp: int = 0) -> bytes:
    """A MAVLink 2 frame of `payload` (plaintext; trimmed here). With `scheme` the payload is encrypted
    and `method` (1..7) goes in incompat bits 5-7; with `signing_key` (32 bytes) the frame is signed with
    `link_id` and `timestamp`. CRC and signature cover the payload as sent."""
    plaintext = trim(payload)
    signed = INCOMPAT_SIGNED if signing_key is not None else 0
    if scheme is None:
        if method:
            raise ValueError("a cipher method needs a scheme")
        body = plaintext
        header = header_v2(len(body), signed, seq, sysid, compid, msgid)
    else:
        if not 1 <= method <= 7:
            raise ValueError("the cipher method is 1..7 (incompat bits 5-7)")
        incompat = method << METHOD_SHIFT | signed
        if scheme == "xor":
            body = xor_cipher(key, plaintext)
        elif scheme == "aes-128-ctr":
            body = aes_128_ctr(key, iv, plaintext)
        elif scheme == "aes-gcm":
            aad = header_v2(len(plaintext) + GCM_OVERHEAD, incompat, seq, sysid, compid, msgid)  # the header below
            body = aes_gcm_payload(key, session_id, counter, plaintext, aad)
        else:
            raise ValueError(f"unknown scheme {scheme!r}: one of {', '.join(SCHEMES)}")
        header = header_v2(len(body), incompat, seq, sysid, compid, msgid)
    if len(body) > 255:
        raise ValueError("the payload on the wire exceeds 255 bytes")
    crc = x25_crc(header[1:] + body)
    crc = x25_crc(bytes([crc_extra]), crc)
    frame = header + body + struct.pack("<H", crc)
    if signing_key is not None:
        if len(signing_key) != 32:
            raise ValueError("a MAVLink signing key is 32 bytes")
        frame += signature_block(signing_key, frame, link_id, timestamp)
    return frame
