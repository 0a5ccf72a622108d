"""`verify` exit codes, `audit` findings, keyrings, JSON Schema of the output, and no secret in any output."""

from __future__ import annotations

import base64
import hashlib
import json
import os
from pathlib import Path

import jsonschema

from tests.conftest import CAPTURES, ROOT, Cli
from tests.support.security import PASSPHRASE, SHA_KEY, command_long, heartbeat, signer, write_raw

SIGNED = str(CAPTURES / "signed_udp.pcap")
SECUREMAV = str(CAPTURES / "securemav_udp.pcap")
DEMO = "passphrase:mavscope-demo"
SCHEMA = json.loads((ROOT / "docs" / "frame.schema.json").read_text())


def test_verify_exit_status(cli: Cli, tmp_path: Path) -> None:
    assert cli("verify", SIGNED, "--key", DEMO)[0] == 0
    status, out, _ = cli("verify", SIGNED, "--key", "passphrase:wrong")
    assert status == 1 and "FAIL" in out
    status, _, err = cli("verify", SIGNED)
    assert status == 2 and "no key material" in err
    assert cli("verify", SIGNED, "--key", "hex:12")[0] == 2
    mav, attacker = signer(SHA_KEY), signer(None)
    first = heartbeat(mav)
    replayed = command_long(mav)
    replay = write_raw(tmp_path, [first, replayed, heartbeat(mav), replayed], "replay.raw")
    status, out, _ = cli("verify", replay, "--key", f"passphrase:{PASSPHRASE}", "--json")
    doc = json.loads(out)
    assert status == 1 and not doc["ok"] and doc["streams"][0]["replay"] == 1
    injected = write_raw(tmp_path, [heartbeat(mav), command_long(attacker)], "inject.raw")
    status, out, _ = cli("verify", injected, "--key", f"passphrase:{PASSPHRASE}", "--json")
    assert status == 1 and json.loads(out)["streams"][0]["unsigned_in_signed_stream"] == 1


def test_audit_weak_passphrase_and_json(cli: Cli, tmp_path: Path) -> None:
    words = tmp_path / "words.txt"
    words.write_text("\n".join(["123456", "password", "mavscope-demo", "qwerty"]) + "\n")
    status, out, _ = cli("audit", SIGNED, "--wordlist", str(words), "--json")
    doc = json.loads(out)
    found = [f for f in doc["findings"] if f["code"] == "weak-passphrase"]
    assert status == 1 and len(found) == 1
    assert "'mavscope-demo'" in found[0]["message"] and "guesses" in found[0]["message"]
    assert set(found[0]) == {"code", "severity", "frames", "message"}
    words.write_text("123456\npassword\n")
    _, out, _ = cli("audit", SIGNED, "--wordlist", str(words), "--json")
    assert [f["code"] for f in json.loads(out)["findings"]] == ["passphrase-not-found"]


def test_audit_qgc_wordlist(cli: Cli, tmp_path: Path) -> None:
    from tests.security.test_signing import QGC_KEY

    mav = signer(QGC_KEY)
    path = write_raw(tmp_path, [heartbeat(mav)])
    words = tmp_path / "w.txt"
    words.write_text(f"{PASSPHRASE}\n")
    _, out, _ = cli("audit", path, "--wordlist", str(words), "--qgc", "--json")
    (f,) = [f for f in json.loads(out)["findings"] if f["code"] == "weak-passphrase"]
    assert "PBKDF2" in f["message"]


def test_audit_keystream_reuse_recovers_payloads_without_the_key(cli: Cli) -> None:
    status, out, _ = cli("audit", SECUREMAV, "--json")
    doc = json.loads(out)
    assert status == 1
    reuse = [f for f in doc["findings"] if f["code"] == "keystream-reuse"]
    assert any("repeat the ciphertext" in f["message"] for f in reuse)
    assert any("keystream prefix" in f["message"] for f in reuse)
    truth = json.loads((CAPTURES / "expected.json").read_text())["securemav_udp.pcap"]["truth"]
    # the recovered fields equal what the key decrypts
    _, jl, _ = cli("read", SECUREMAV, "--cipher", f"{truth['aes_method']}=aes-128-ctr:hex:{truth['aes_key']}",
                   "-T", "jsonl")
    by_frame = {(r["frame"]): r for r in map(json.loads, jl.splitlines())}
    full = [r for r in doc["recovered"] if r["fields"] is not None]
    assert len(full) >= 14  # the heartbeats, completely
    for r in full:
        assert r["fields"] == by_frame[r["frame"]]["fields"]
    assert len(doc["recovered"]) == 103  # every other encrypted frame, up to the recovered prefix


def test_audit_known_plaintext_guess(cli: Cli, tmp_path: Path) -> None:
    from tests.security.test_ciphers import SECUREMAV_KEY, ctr_encrypt, securemav_frame

    mav = signer(None, sysid=1, compid=1)
    hb = [mav.heartbeat_encode(2, 12, 81, 0, 4, 3) for _ in range(3)]
    frames = [securemav_frame(bytes(m.pack(mav)), 2, ctr_encrypt(SECUREMAV_KEY), m.crc_extra) for m in hb]
    path = write_raw(tmp_path, frames)
    guess = bytes(hb[0].pack(mav))[10:19].hex()
    _, out, _ = cli("audit", path, "--known-plaintext", f"HEARTBEAT={guess}", "--json")
    doc = json.loads(out)
    assert any("known-plaintext" in f["message"] for f in doc["findings"])
    assert [r["fields"]["type"] for r in doc["recovered"]] == [2, 2]


def test_audit_summaries_of_commands_capture(cli: Cli) -> None:
    status, out, _ = cli("audit", str(CAPTURES / "commands_ack.pcap"), "--json")
    codes = [f["code"] for f in json.loads(out)["findings"]]
    assert "key-leak" in codes and status == 1


def test_output_validates_against_the_schema(cli: Cli) -> None:
    truth = json.loads((CAPTURES / "expected.json").read_text())
    kx, sm = truth["key_exchange_udp.pcap"]["truth"], truth["securemav_udp.pcap"]["truth"]
    runs = [(SIGNED, "--key", DEMO), (SECUREMAV, "--key", DEMO),
            (SECUREMAV, "--cipher", f"2=aes-128-ctr:hex:{sm['aes_key']}"),
            (str(CAPTURES / "key_exchange_udp.pcap"), "--ecdh-private", f"hex:{kx['gcs_private']}"),
            (str(CAPTURES / "key_exchange_udp.pcap"),)]
    validator = jsonschema.Draft202012Validator(SCHEMA)
    for argv in runs:
        status, out, err = cli("read", *argv, "-T", "jsonl")
        assert status == 0, err
        for line in out.splitlines():
            validator.validate(json.loads(line))


def test_keyring_names_and_permission_warning(cli: Cli, tmp_path: Path) -> None:
    ring = tmp_path / "ring.toml"
    ring.write_text(f'ciphers = ["2=aes-128-ctr:hex:{"33" * 16}"]\n\n[keys]\nvehicle = "passphrase:mavscope-demo"\n'
                    f'other = "hex:{"22" * 32}"\n')
    os.chmod(ring, 0o644)
    status, out, err = cli("read", SIGNED, "--key", f"file:{ring}", "-T", "jsonl", "-c", "1")
    assert status == 0 and json.loads(out)["signature"]["key"] == "vehicle"
    assert "readable by group or others" in err and str(ring) in err and "mavscope-demo" not in err
    os.chmod(ring, 0o600)
    status, out, err = cli("verify", SIGNED, environ={"MAVSCOPE_KEYRING": str(ring)})
    assert status == 0 and err == "" and "vehicle" in out


def test_no_secret_in_any_output(cli: Cli, tmp_path: Path) -> None:
    key = hashlib.sha256(b"mavscope-demo").digest()
    secrets = [key.hex(), key.hex().upper(), base64.b64encode(key).decode(), "mavscope-demo",
               "7c852089ffdb16126dbee7c968a751b5", "7C852089FFDB16126DBEE7C968A751B5"]
    truth = json.loads((CAPTURES / "expected.json").read_text())["key_exchange_udp.pcap"]["truth"]
    ecdh = truth["gcs_private"]
    secrets += [ecdh] + [e["signing_key"] for e in truth["epochs"]] + [e["aes_gcm_key"] for e in truth["epochs"]]
    ring = tmp_path / "ring.toml"
    ring.write_text('[keys]\nv = "passphrase:mavscope-demo"\n')
    os.chmod(ring, 0o600)
    cipher = "2=aes-128-ctr:hex:7C852089FFDB16126DBEE7C968A751B5"
    runs = [
        ("read", SIGNED, "--key", DEMO, "-V", "-x", "-c", "5"),
        ("read", SIGNED, "--key", f"hex:{key.hex()}", "-T", "jsonl"),
        ("read", SIGNED, "--key", f"b=base64:{base64.b64encode(key).decode()}", "-T", "json", "-c", "3"),
        ("read", SECUREMAV, "--key", f"file:{ring}", "--cipher", cipher, "-V"),
        ("read", str(CAPTURES / "key_exchange_udp.pcap"), "--ecdh-private", f"hex:{ecdh}", "-V", "-T", "text"),
        ("verify", SIGNED, "--key", DEMO),
        ("verify", SIGNED, "--key", DEMO, "--json"),
        ("audit", SECUREMAV, "--key", DEMO, "--cipher", cipher),
        ("audit", SECUREMAV, "--key", DEMO, "--json"),
        # refused key specs: the message names the problem, never the value
        ("read", SIGNED, "--key", f"hex:{key.hex()}0"),
        ("read", SIGNED, "--key", "mavscope-demo"),
        ("read", SIGNED, "--cipher", "2=aes-128-ctr:hex:7C852089FFDB16126DBEE7C968A751B5FF"),
        ("read", SIGNED, "--ecdh-private", f"hex:{ecdh[:-2]}"),
    ]
    for argv in runs:
        _, out, err = cli(*argv)
        for s in secrets:
            assert s not in out and s not in err, (argv, s)
    from mavscope.security.keys import build_material

    m = build_material([DEMO], ["2=aes-128-ctr:hex:7C852089FFDB16126DBEE7C968A751B5"], [f"hex:{ecdh}"])
    for s in secrets:
        assert s not in repr(m) and s not in repr(m.signing) and s not in repr(m.ciphers)
