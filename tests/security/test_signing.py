"""Signature verdicts on frames signed by pymavlink (an independent implementation)."""

from __future__ import annotations

import hashlib
import threading
from pathlib import Path

import pytest

from mavscope.capture.base import LINKTYPE_MAVLINK_TLOG, Record
from mavscope.mavlink.frame import Frame, SignatureReason
from mavscope.pipeline.dissect import Anomaly, Dissector
from mavscope.security.keys import QGC_SALT, KeyMaterial, SigningKey, build_material
from mavscope.security.stage import SecurityStage
from tests.conftest import Cli
from tests.support.security import (
    EPOCH_2026,
    PASSPHRASE,
    SHA_KEY,
    command_long,
    fix_crc,
    heartbeat,
    radio_status,
    signer,
    statuses,
    write_raw,
)

# QGroundControl's derivation, computed once here with hashlib (600000 iterations: the real cost, once).
QGC_KEY = hashlib.pbkdf2_hmac("sha256", PASSPHRASE.encode(), QGC_SALT, 600_000, 32)


def test_passphrase_sha256_frames_verify(cli: Cli, tmp_path: Path) -> None:
    mav = signer(SHA_KEY)
    path = write_raw(tmp_path, [heartbeat(mav), command_long(mav), heartbeat(mav)])
    rows = cli.jsonl(path, "--key", f"gcs=passphrase:{PASSPHRASE}")
    assert statuses(rows) == ["valid"] * 3
    assert {r["signature"]["key"] for r in rows} == {"gcs"}


def test_qgc_pbkdf2_derivation_verifies(cli: Cli, tmp_path: Path) -> None:
    mav = signer(QGC_KEY)
    path = write_raw(tmp_path, [heartbeat(mav), heartbeat(mav)])
    rows = cli.jsonl(path, "--key", f"qgc:{PASSPHRASE}")  # mavscope derives it (600000 iterations)
    assert statuses(rows) == ["valid", "valid"]
    assert rows[0]["signature"]["key"] == "key1"
    # the other derivation of the same passphrase is another key
    assert statuses(cli.jsonl(path, "--key", f"passphrase:{PASSPHRASE}")) == ["invalid", "invalid"]


def test_tampered_payload_with_fixed_crc_is_invalid(cli: Cli, tmp_path: Path) -> None:
    mav = signer(SHA_KEY)
    good = heartbeat(mav)
    cmd = bytearray(command_long(mav))
    cmd[10] ^= 0x40  # param1 changed...
    fix_crc(cmd)  # ...and the CRC made right again: only the signature can tell
    path = write_raw(tmp_path, [good, bytes(cmd), heartbeat(mav)])
    rows = cli.jsonl(path, "--key", f"passphrase:{PASSPHRASE}")
    assert [r["crc_status"] for r in rows] == ["ok", "ok", "ok"]
    assert statuses(rows) == ["valid", "invalid", "valid"]
    assert "key" not in rows[1]["signature"]


def test_old_frame_sent_again_is_a_replay(cli: Cli, tmp_path: Path) -> None:
    mav = signer(SHA_KEY)
    first, second, third = heartbeat(mav), command_long(mav), heartbeat(mav)
    path = write_raw(tmp_path, [first, second, third, second])  # the command again, later
    rows = cli.jsonl(path, "--key", f"passphrase:{PASSPHRASE}")
    assert statuses(rows) == ["valid", "valid", "valid", "replay"]
    assert rows[3]["signature"]["key"] == "key1"  # the MAC verifies: it is a replay, not a forgery


def test_forged_future_timestamp_does_not_block_genuine_frames(cli: Cli, tmp_path: Path) -> None:
    """Stream state advances only after a MAC verifies (pymavlink advances it before)."""
    mav = signer(SHA_KEY)
    forger = signer(b"\x01" * 32, timestamp=EPOCH_2026 + 10**9)  # same stream, wrong key, far future
    path = write_raw(tmp_path, [heartbeat(mav), heartbeat(forger), heartbeat(mav), heartbeat(mav)])
    assert statuses(cli.jsonl(path, "--key", f"passphrase:{PASSPHRASE}")) == ["valid", "invalid", "valid", "valid"]


def test_injected_unsigned_command_is_noted(cli: Cli, tmp_path: Path) -> None:
    mav = signer(SHA_KEY)
    attacker = signer(None)  # same sysid/compid as the GCS, no key
    path = write_raw(tmp_path, [heartbeat(mav), command_long(attacker), radio_status(attacker), heartbeat(mav)])
    rows = cli.jsonl(path, "--key", f"passphrase:{PASSPHRASE}")
    assert statuses(rows) == ["valid", None, None, "valid"]
    codes = [[n["code"] for n in r["notes"]] for r in rows]
    assert "unsigned-in-signed-stream" in codes[1]  # the injected COMMAND_LONG
    assert "unsigned-in-signed-stream" not in codes[2]  # RADIO_STATUS is exempt
    # without a key, "signed" (with a good CRC) is what marks a signing sender
    rows = cli.jsonl(path)
    assert "unsigned-in-signed-stream" in [n["code"] for n in rows[1]["notes"]]


def test_wrong_key_verifies_nothing(cli: Cli, tmp_path: Path) -> None:
    mav = signer(SHA_KEY)
    path = write_raw(tmp_path, [heartbeat(mav), command_long(mav), heartbeat(mav)])
    assert statuses(cli.jsonl(path, "--key", "passphrase:not the passphrase")) == ["invalid"] * 3
    assert statuses(cli.jsonl(path)) == ["no-key"] * 3


def test_key_identified_among_several(cli: Cli, tmp_path: Path) -> None:
    k_vehicle, k_gcs = hashlib.sha256(b"vehicle").digest(), hashlib.sha256(b"gcs").digest()
    veh = signer(k_vehicle, sysid=1, compid=1, link_id=0)
    gcs = signer(k_gcs)
    path = write_raw(tmp_path, [heartbeat(veh), heartbeat(gcs), heartbeat(veh), command_long(gcs)])
    rows = cli.jsonl(path, "--key", "decoy=hex:" + "11" * 32, "--key", f"veh=hex:{k_vehicle.hex()}",
                     "--key", "passphrase:gcs")
    assert statuses(rows) == ["valid"] * 4
    assert [r["signature"]["key"] for r in rows] == ["veh", "key1", "veh", "key1"]


def test_gomavlib_vectors_verify_with_key_4f(cli: Cli, real_captures: Path) -> None:
    path = real_captures / "gomavlib_signed_testvectors_key4F_DERIVED.raw"
    rows = cli.jsonl(str(path), "--key", "gomavlib=hex:" + "4f" * 32)
    assert [(r["msgname"], r["signature"]["link_id"], r["signature"]["timestamp"]) for r in rows] == \
        [("HEARTBEAT", 1, 2), ("OPTICAL_FLOW", 3, 4)]
    assert statuses(rows) == ["valid", "valid"]
    assert statuses(cli.jsonl(str(path), "--key", "hex:" + "4e" * 32)) == ["invalid", "invalid"]


def test_setup_signing_leaks_the_key_and_can_be_used(cli: Cli, tmp_path: Path) -> None:
    leaked = hashlib.sha256(b"leaked").digest()
    plain = signer(None)
    setup = bytes(plain.setup_signing_encode(1, 1, leaked, EPOCH_2026).pack(plain))
    mav = signer(leaked, timestamp=EPOCH_2026 + 5)
    path = write_raw(tmp_path, [setup, heartbeat(mav), command_long(mav)])
    rows = cli.jsonl(path)
    assert [n["code"] for n in rows[0]["notes"]] == ["key-leak"]
    assert leaked.hex() not in rows[0]["notes"][0]["message"]
    assert statuses(rows) == [None, "no-key", "no-key"]
    rows = cli.jsonl(path, "--use-leaked-keys")
    assert statuses(rows) == [None, "valid", "valid"]
    assert rows[1]["signature"]["key"] == "leaked-1"


def test_signature_skew_is_reported(tmp_path: Path) -> None:
    from mavscope.security.signing import SignatureVerifier

    mav = signer(SHA_KEY)
    frame = heartbeat(mav)
    v = SignatureVerifier([SigningKey("k", SHA_KEY)])
    verdict = v.verify(frame, 255, 190, 1, EPOCH_2026, capture_time=1_773_482_400.0 - 90.0,
                       sig_unix_time=1_773_482_400.0)
    assert verdict.status.value == "valid" and verdict.reason is SignatureReason.NEW_STREAM
    assert verdict.skew == pytest.approx(90.0)


def test_key_specs() -> None:
    m = build_material(["a=hex:" + "00" * 32, "base64:" + "AAAA" * 10 + "AAA=", "passphrase:x", "b=passphrase:y=z"])
    assert [k.name for k in m.signing] == ["a", "key1", "key2", "b"]
    assert m.signing[3].secret == hashlib.sha256(b"y=z").digest()
    assert repr(m.signing[0]) == "SigningKey('a')"
    from mavscope.errors import UsageError

    for bad in ("hex:abcd", "nope:xx", "justtext", "base64:!!!!", "a=hex:" + "00" * 32 + "0"):
        with pytest.raises(UsageError):
            build_material([bad])
    with pytest.raises(UsageError, match="twice"):
        build_material(["a=passphrase:1", "a=passphrase:2"])


def test_key_material_handed_to_a_running_stage_is_taken_between_two_frames(dialect) -> None:  # type: ignore[no-untyped-def]
    """Live capture hands new keys over from another thread: the stage takes them before its next
    frame, on its own thread, where `then` judges the frames so far again (rebuilding the replay
    state), so that the last frame, the third sent again, is a replay."""
    mav = signer(SHA_KEY)
    raws = [heartbeat(mav), command_long(mav), heartbeat(mav), command_long(mav)]
    raws.append(raws[2])
    records = [Record(n, 1_773_482_400.0 + n, LINKTYPE_MAVLINK_TLOG, raw, 8, len(raw))
               for n, raw in enumerate(raws, 1)]
    dissected = [f for f in Dissector(dialect).run(records) if type(f) is not Anomaly]
    stage = SecurityStage()
    material = build_material([f"live={'passphrase:' + PASSPHRASE}"])
    seen: list[Frame] = []
    again: list[tuple[str, list[Frame]]] = []

    def then(s: SecurityStage) -> None:
        again.append((threading.current_thread().name, list(s.run(f._replace(security=None) for f in seen))))

    def feed():  # type: ignore[no-untyped-def]
        for n, frame in enumerate(dissected):
            if n == 2:  # the UI thread hands the key over while the stage runs
                t = threading.Thread(target=stage.replace_material, args=(material, then))
                t.start()
                t.join()
            yield frame

    def verdicts(frames: list[Frame]) -> list[tuple[str, str | None] | None]:
        return [(f.security.signature_status.value, f.security.key) if f.security else None for f in frames]

    for f in stage.run(feed()):
        seen.append(f)
    valid = ("valid", "live")
    assert verdicts(seen) == [None, None, valid, valid, ("replay", "live")]
    assert len(again) == 1 and again[0][0] == threading.current_thread().name  # on the stage's thread
    assert verdicts(again[0][1]) == [valid, valid]  # the two frames before the key, judged again
    stage.replace_material(KeyMaterial())  # no keys: starts over, nothing verifies any more
    assert verdicts(list(stage.run(dissected[:1]))) == [None]
    assert stage._incoming == [] and stage.verifier.keys == []
