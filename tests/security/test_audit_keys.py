"""Key guessing in `audit` (well-known keys, wordlists over every signing stream) and MAVLink v1 from
signing senders in `verify`; inputs built here with pymavlink, expectations from how they were built."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from pymavlink.dialects.v10 import common as v1
from pymavlink.dialects.v20 import common as v2

from tests.conftest import Cli
from tests.support.security import EPOCH_2026, heartbeat, signer, write_raw


def _codes(out: str) -> dict[str, list[dict]]:
    found: dict[str, list[dict]] = {}
    for f in json.loads(out)["findings"]:
        found.setdefault(f["code"], []).append(f)
    return found


def test_audit_reports_a_well_known_key_unasked(cli: Cli, tmp_path: Path) -> None:
    """A vehicle signing with the all-zero key (a default never changed): found without --wordlist."""
    mav = signer(bytes(32), sysid=1, compid=1, link_id=0)
    path = write_raw(tmp_path, [heartbeat(mav) for _ in range(3)])
    status, out, _ = cli("audit", path, "--json")
    (found,) = _codes(out)["default-key"]
    assert status == 1 and found["severity"] == "error" and "all-zero key" in found["message"]
    assert found["frames"] == [1]  # the stream's first signed frame verifies


def test_two_keys_found_in_one_pass_despite_a_forged_first_frame(cli: Cli, tmp_path: Path) -> None:
    """Vehicle 1/1 signs with SHA-256("alpha"), the GCS 255/190 with SHA-256("bravo"); the capture starts
    with a signed frame of the vehicle's stream whose MAC is forged (random bytes)."""
    vehicle = signer(hashlib.sha256(b"alpha").digest(), sysid=1, compid=1, link_id=0, timestamp=EPOCH_2026)
    gcs = signer(hashlib.sha256(b"bravo").digest(), sysid=255, compid=190, link_id=1, timestamp=EPOCH_2026)
    forged = bytearray(heartbeat(vehicle))
    forged[-6:] = bytes.fromhex("0123456789ab")
    frames = [bytes(forged)] + [f for _ in range(5) for f in (heartbeat(vehicle), heartbeat(gcs))]
    words = tmp_path / "words.txt"
    words.write_bytes(b"zulu\nbravo\n" + b"x" * 5000 + b"\nalpha\n")  # an over-long line is skipped
    status, out, _ = cli("audit", write_raw(tmp_path, frames), "--wordlist", str(words), "--json")
    weak = {f["message"].split("'")[1]: f for f in _codes(out)["weak-passphrase"]}
    assert set(weak) == {"alpha", "bravo"} and status == 1
    assert "1/1 link 0" in weak["alpha"]["message"] and weak["alpha"]["frames"] == [2]  # not the forged one
    assert "255/190 link 1" in weak["bravo"]["message"] and weak["bravo"]["frames"] == [3]
    assert "1 over-long line(s) skipped" in weak["alpha"]["message"]
    assert "passphrase-not-found" not in _codes(out)


def test_a_wordlist_without_line_breaks_stops(cli: Cli, tmp_path: Path) -> None:
    """`--wordlist /dev/zero` once grew until killed: reading stops after 1 MiB without a line break."""
    path = write_raw(tmp_path, [heartbeat(signer(hashlib.sha256(b"alpha").digest()))])
    status, out, _ = cli("audit", path, "--wordlist", "/dev/zero", "--json")
    (nf,) = _codes(out)["passphrase-not-found"]
    assert "reading stopped: no line break" in nf["message"] and "(0 words" in nf["message"]


def test_v1_frames_from_a_signing_sender_are_not_injections(cli: Cli, tmp_path: Path) -> None:
    """Mission Planner's pattern: one signed v2 STATUSTEXT, then MAVLink v1 (which cannot be signed)."""
    key = hashlib.sha256(b"mp").digest()
    mav2 = signer(key, sysid=255, compid=190, link_id=0)
    first = bytes(mav2.statustext_encode(6, b"signing on").pack(mav2))
    mav1 = v1.MAVLink(None, srcSystem=255, srcComponent=190)
    later = [bytes(mav1.heartbeat_encode(6, 8, 0, 0, 4, 3).pack(mav1)) for _ in range(4)]
    unsigned_v2 = bytes(v2.MAVLink(None, srcSystem=255, srcComponent=190).heartbeat_encode(6, 8, 0, 0, 4, 3)
                        .pack(v2.MAVLink(None, srcSystem=255, srcComponent=190)))
    path = write_raw(tmp_path, [first, *later, unsigned_v2])
    status, out, _ = cli("verify", path, "--key", "hex:" + key.hex(), "--json")
    doc = json.loads(out)
    (row,) = doc["streams"]
    assert (row["v1_in_signed_stream"], row["unsigned_in_signed_stream"], row["valid"]) == (4, 1, 1)
    assert doc["signing_in_force"] is False and status == 1  # the unsigned v2 frame is an injection
    status, out, _ = cli("verify", write_raw(tmp_path, [first, *later], "v1.raw"), "--key", "hex:" + key.hex())
    assert status == 0 and "signing is not in force: 4 MAVLink v1 frame(s)" in out
    rows = cli.jsonl(write_raw(tmp_path, [first, *later], "v1b.raw"), "--key", "hex:" + key.hex())
    assert [n["code"] for r in rows for n in r["notes"]] == ["v1-in-signed-stream"] * 4


def test_crack_one_frame_finds_its_passphrase() -> None:
    """`crack_sha256` (the benchmark's entry) on one frame pymavlink signed with SHA-256("hunter2"): it
    once raised AttributeError (its stand-in target had no record number)."""
    import hashlib

    from mavscope.security.passphrase import crack_sha256
    from tests.support.security import heartbeat, signer

    raw = bytes(heartbeat(signer(hashlib.sha256(b"hunter2").digest())))
    result = crack_sha256(raw, [b"password", b"hunter2", b"letmein"])
    assert result.found == {(0, 0, 0): ("hunter2", 0)} and result.guesses == 2
