"""Payload decryption: SecureMAV XOR and AES-128-CTR frames built here with `cryptography` directly,
the aes-gcm profile, and the ECDH key-exchange capture with re-keying. Frames that need the full
encoder (signed over the ciphertext, aes-gcm) come from the capture generator's `encode_frame`, written
from docs/security.md independently of mavscope's code."""

from __future__ import annotations

import hashlib
import json
import struct
from pathlib import Path

from cryptography.hazmat.primitives.ciphers import Cipher, algorithms, modes

from mavscope.security.ciphers import GCM_OVERHEAD
from scripts.capgen.encode import encode_frame
from tests.conftest import CAPTURES, Cli
from tests.support.security import SHA_KEY, signer, statuses, write_raw

SECUREMAV_KEY = bytes.fromhex("7C852089FFDB16126DBEE7C968A751B5")


def securemav_frame(msg_frame: bytes, method: int, encrypt, crc_extra: int) -> bytes:  # type: ignore[no-untyped-def]
    """Re-encode an unsigned pymavlink v2 frame as SecureMAV sends it: payload encrypted, method in
    incompat bits 5-7, CRC over the ciphertext (built here without mavscope's encoder)."""
    from pymavlink.dialects.v20 import all as v2

    length = msg_frame[1]
    cipher_payload = encrypt(msg_frame[10:10 + length])
    header = bytearray(msg_frame[:10])
    header[1] = len(cipher_payload)
    header[2] = method << 5
    crc = v2.x25crc(bytes(header[1:]) + cipher_payload)
    crc.accumulate(bytes([crc_extra]))
    return bytes(header) + cipher_payload + struct.pack("<H", crc.crc)


def attitude(mav, t: int):  # type: ignore[no-untyped-def]
    return mav.attitude_encode(t, 0.125, -0.25, 1.5, 0.01, 0.02, -0.03)


def test_securemav_xor_method_7_decrypts_without_options(cli: Cli, tmp_path: Path) -> None:
    mav = signer(None, sysid=1, compid=1)
    msgs = [attitude(mav, 1000 + i) for i in range(3)]
    plain = [bytes(m.pack(mav)) for m in msgs]
    frames = [securemav_frame(p, 7, lambda b: bytes(x ^ 0xAB for x in b), m.crc_extra) for p, m in zip(plain, msgs)]
    rows = cli.jsonl(write_raw(tmp_path, frames))
    assert all(r["crc_status"] == "ok" for r in rows)
    assert [r["encryption"] for r in rows] == [{"method": 7, "scheme": "xor", "status": "decrypted"}] * 3
    assert [r["fields"]["time_boot_ms"] for r in rows] == [1000, 1001, 1002]
    # a float field's JSON number reads back as the float32 that was sent (docs/json-format.md): -0.03 packed
    # by pymavlink above, compared as float32 bits
    yawspeed = rows[0]["fields"]["yawspeed"]
    assert rows[0]["fields"]["roll"] == 0.125 and struct.pack("<f", yawspeed) == struct.pack("<f", -0.03)


def ctr_encrypt(key: bytes):  # type: ignore[no-untyped-def]
    def enc(data: bytes) -> bytes:  # the counter restarts for every frame, as SecureMAV does
        e = Cipher(algorithms.AES(key), modes.CTR(b"\x00" * 16)).encryptor()
        return e.update(data) + e.finalize()
    return enc


def test_securemav_aes_128_ctr_decrypts_to_the_plaintext_fields(cli: Cli, tmp_path: Path) -> None:
    mav = signer(None, sysid=1, compid=1)
    msgs = [attitude(mav, 2000 + i) for i in range(3)]
    frames = [securemav_frame(bytes(m.pack(mav)), 3, ctr_encrypt(SECUREMAV_KEY), m.crc_extra) for m in msgs]
    path = write_raw(tmp_path, frames)
    rows = cli.jsonl(path, "--cipher", f"3=aes-128-ctr:hex:{SECUREMAV_KEY.hex()}")
    assert [r["encryption"]["status"] for r in rows] == ["decrypted"] * 3
    assert [r["fields"]["time_boot_ms"] for r in rows] == [2000, 2001, 2002]
    assert rows[1]["fields"]["pitch"] == -0.25
    # without the cipher: header, CRC listed; fields null; status no-key
    rows = cli.jsonl(path)
    assert [r["crc_status"] for r in rows] == ["ok"] * 3
    assert rows[0]["fields"] is None
    assert rows[0]["encryption"]["status"] == "no-key" and rows[0]["encryption"]["scheme"] is None
    # a wrong key decrypts to garbage that is still "decrypted" (CTR has no integrity), never the right fields
    rows = cli.jsonl(path, "--cipher", "3=aes-128-ctr:hex:" + "00" * 16)
    assert rows[0]["fields"] is None or rows[0]["fields"]["time_boot_ms"] != 2000


def test_signature_is_checked_over_the_ciphertext(cli: Cli, tmp_path: Path) -> None:
    mav = signer(None, sysid=1, compid=1)
    m = attitude(mav, 5)
    payload = bytes(m.pack(mav))[10:-2]
    frame = encode_frame(30, payload, m.crc_extra, method=3, scheme="aes-128-ctr", key=SECUREMAV_KEY,
                         signing_key=SHA_KEY, link_id=0, timestamp=100)
    rows = cli.jsonl(write_raw(tmp_path, [frame]), "--key", f"hex:{SHA_KEY.hex()}")
    assert rows[0]["signature"]["status"] == "valid"
    assert rows[0]["encryption"]["status"] == "no-key"  # no cipher: still listed with its verdicts


def test_aes_gcm_round_trip_and_tamper_rejection(cli: Cli, tmp_path: Path) -> None:
    master = hashlib.sha256(b"gcm master").digest()
    mav = signer(None, sysid=1, compid=1)
    msgs = [attitude(mav, 3000 + i) for i in range(3)]
    frames = [encode_frame(30, bytes(m.pack(mav))[10:-2], m.crc_extra, seq=i, method=5, scheme="aes-gcm", key=master,
                           session_id=7, counter=i) for i, m in enumerate(msgs)]
    assert all(f[1] == len(bytes(msgs[0].pack(mav))[10:-2]) + GCM_OVERHEAD for f in frames)
    tampered = bytearray(frames[1])
    tampered[10 + 12] ^= 1  # one ciphertext bit
    from tests.support.security import fix_crc

    fix_crc(tampered)  # CRC made right: only the tag can tell
    header_changed = bytearray(frames[2])
    header_changed[5] = 2  # sysid: part of the associated data
    fix_crc(header_changed)
    path = write_raw(tmp_path, [frames[0], bytes(tampered), frames[2], bytes(header_changed)])
    rows = cli.jsonl(path, "--cipher", f"5=aes-gcm:hex:{master.hex()}")
    assert [r["crc_status"] for r in rows] == ["ok"] * 4
    assert [r["encryption"]["status"] for r in rows] == ["decrypted", "failed", "decrypted", "failed"]
    assert rows[0]["fields"]["time_boot_ms"] == 3000 and rows[2]["fields"]["time_boot_ms"] == 3002
    assert rows[1]["fields"] is None and "tag" in rows[1]["encryption"]["reason"]
    rows = cli.jsonl(path, "--cipher", "5=aes-gcm:hex:" + "00" * 32)
    assert {r["encryption"]["status"] for r in rows} == {"failed"}


def test_aes_gcm_nonce_reuse_is_noted(cli: Cli, tmp_path: Path) -> None:
    master = b"\x42" * 32
    mav = signer(None, sysid=1, compid=1)
    a, b = attitude(mav, 1), attitude(mav, 2)
    frames = [encode_frame(30, bytes(m.pack(mav))[10:-2], m.crc_extra, method=5, scheme="aes-gcm", key=master,
                           session_id=1, counter=9) for m in (a, b)]
    rows = cli.jsonl(write_raw(tmp_path, frames), "--cipher", f"5=aes-gcm:hex:{master.hex()}")
    assert [n["code"] for n in rows[1]["notes"] if n["code"] == "nonce-reuse"] == ["nonce-reuse"]


def _kex_truth() -> dict:
    return json.loads((CAPTURES / "expected.json").read_text())["key_exchange_udp.pcap"]["truth"]


def test_key_exchange_capture_verifies_and_decrypts_across_rekeying(cli: Cli) -> None:
    truth = _kex_truth()
    path = str(CAPTURES / "key_exchange_udp.pcap")
    rows = cli.jsonl(path, "--ecdh-private", f"hex:{truth['gcs_private']}")
    signed = [r for r in rows if r["signature"]]
    assert signed and {r["signature"]["status"] for r in signed} == {"valid"}
    assert [k for k in dict.fromkeys(r["signature"]["key"] for r in signed)] == ["ecdh-1", "ecdh-2", "ecdh-3"]
    enc = [r for r in rows if r["encryption"]]
    assert len(enc) == truth["encrypted_frames"]
    assert {r["encryption"]["status"] for r in enc} == {"decrypted"}
    assert all(r["fields"] is not None for r in rows)
    derived = [n["message"] for r in rows for n in r["notes"] if "keys derived" in n["message"]]
    assert len(derived) == len(truth["epochs"])
    # the documented per-epoch keys are the ones mavscope derives
    e2 = truth["epochs"][1]
    rows2 = cli.jsonl(path, "--key", f"e2=hex:{e2['signing_key']}", "--cipher", f"6=aes-gcm:hex:{e2['aes_gcm_key']}")
    two = [r for r in rows2 if r["signature"] and r["signature"]["status"] == "valid"]
    assert two and {r["signature"]["key"] for r in two} == {"e2"}
    # without the private key: no-key verdicts, fields of encrypted frames null
    rows3 = cli.jsonl(path)
    assert set(statuses(rows3)) <= {None, "no-key"}
    assert {r["encryption"]["status"] for r in rows3 if r["encryption"]} == {"no-key"}
