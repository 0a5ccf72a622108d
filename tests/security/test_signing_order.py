"""Signing order (issue 35, item 4): the verdict on an unsigned frame claiming a signing sender does not
depend on where it lies in the capture.

A receiver with signing configured refuses unsigned frames (but RADIO_STATUS) whether or not it has yet
seen a signed frame of that sender (MAVLink's signing specification: once signing is set up, unsigned
packets are rejected, ArduPilot's accept_unsigned callback taking RADIO_STATUS alone), and offline the whole
capture is known. So a sender that signs anywhere in the capture makes an unsigned frame claiming it an
`unsigned-in-signed-stream` (and a MAVLink v1 frame a `v1-in-signed-stream`), before its first signed frame
as after it. The frames are signed by pymavlink (tests/support/security.py); each test builds the same
frames in two orders and expects the same verify exit status and counts, and the same audit findings
(but the frame numbers, which follow the order).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.native.engines import PURE
from tests.support.pmav import heartbeat as heartbeat_v1
from tests.support.pmav import mav1
from tests.support.security import PASSPHRASE, SHA_KEY, command_long, heartbeat, signer, write_raw

KEY = ["--key", f"passphrase:{PASSPHRASE}"]


def captures(tmp_path: Path) -> dict[str, str]:
    """The vehicle-side GCS 255/190 signs three HEARTBEATs; an attacker sends an unsigned COMMAND_LONG and a
    MAVLink v1 HEARTBEAT as 255/190. "before": the attacker's frames first; "after": last."""
    gcs = signer(SHA_KEY, 255, 190)
    signed = []
    for _ in range(3):
        signed.append(heartbeat(gcs))
        gcs.signing.timestamp += 1
    attacker = signer(None, 255, 190)
    forged = [command_long(attacker), heartbeat_v1(mav1(255, 190))]
    return {"before": write_raw(tmp_path, forged + signed, "before.raw"),
            "after": write_raw(tmp_path, signed + forged, "after.raw")}


def verify(cli: Cli, path: str) -> tuple[int, dict]:
    r = cli("verify", path, *KEY, "--json")
    doc = json.loads(r.out)
    return r.status, doc


@pytest.mark.parametrize("keys", [KEY, []], ids=["key", "no-key"])
def test_audit_does_not_depend_on_the_order(cli: Cli, tmp_path: Path, keys: list[str]) -> None:
    paths = captures(tmp_path)
    found = {}
    for order, path in paths.items():
        r = cli("audit", path, "--json", *keys)
        assert r.status == 1, order
        found[order] = {f["code"]: len(f["frames"]) for f in json.loads(r.out)["findings"]}
        text = cli("audit", path, *keys)
        assert "unsigned-in-signed-stream" in text.out and "v1-in-signed-stream" in text.out
        assert cli("audit", path, *keys, environ=PURE).out == text.out
    assert found["before"] == found["after"]
    assert found["before"]["unsigned-in-signed-stream"] == 1 and found["before"]["v1-in-signed-stream"] == 1


def test_verify_does_not_depend_on_the_order(cli: Cli, tmp_path: Path) -> None:
    paths = captures(tmp_path)
    rows = {}
    for order, path in paths.items():
        status, doc = verify(cli, path)
        assert status == 1 and not doc["ok"] and not doc["signing_in_force"], order
        (row,) = [s for s in doc["streams"] if (s["sysid"], s["compid"]) == (255, 190)]
        rows[order] = row
        assert [p["message"].split(" from")[0] for p in doc["problems"]] == ["unsigned COMMAND_LONG"]
        text = cli("verify", path, *KEY)
        assert text.status == 1 and "FAIL" in text.out
        for fmt in ((), ("--json",)):
            pure = cli("verify", path, *KEY, *fmt, environ=PURE)
            native = cli("verify", path, *KEY, *fmt, environ={})
            assert (native.out, native.err, native.status) == (pure.out, pure.err, pure.status)
    assert rows["before"] == rows["after"]
    assert rows["before"]["unsigned_in_signed_stream"] == 1 and rows["before"]["v1_in_signed_stream"] == 1
    assert rows["before"]["valid"] == 3


def test_a_sender_that_never_signs_is_not_judged(cli: Cli, tmp_path: Path) -> None:
    """Unsigned frames of 255/190 with signed frames only from another sender (1/1): no downgrade."""
    vehicle = signer(SHA_KEY, 1, 1)
    path = write_raw(tmp_path, [command_long(signer(None, 255, 190)), heartbeat(vehicle)], "other.raw")
    status, doc = verify(cli, path)
    assert status == 0 and doc["ok"]
    r = cli("audit", path, "--json", *KEY)
    assert "unsigned-in-signed-stream" not in {f["code"] for f in json.loads(r.out)["findings"]}
