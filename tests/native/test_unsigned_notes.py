"""Unsigned frames of a sender that signs: the note the native walker writes is the security stage's.

security/stage.py's rule (the reference, and the one place the note's text is made: `unsigned_note`): an
unsigned frame whose sender has sent a signed frame (CRC good) earlier in the capture, or earlier in the
same datagram, gets `unsigned-in-signed-stream` (MAVLink 2) or `v1-in-signed-stream` (MAVLink 1), but
RADIO_STATUS, which radios add unsigned. The native walk writes those frames itself (walk.c, with the note's
JSON cut from `unsigned_note`'s), so `read -T jsonl` and the summary lines print the same bytes on both
engines, with no record handed back. The expected notes are written out here by hand from that rule.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink.dialects.v10 import common as v1

from tests.conftest import Cli
from tests.support.flows import write_udp_pcap
from tests.support.security import SHA_KEY, heartbeat, radio_status, signer

GCS, VEHICLE = ("10.0.0.1", 14550), ("10.0.0.2", 14580)


def _attitude(mav: object) -> bytes:
    return bytes(mav.attitude_encode(1000, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0).pack(mav))  # type: ignore[attr-defined]


def _capture(tmp: Path) -> tuple[Path, list[tuple[int, str | None, str | None]]]:
    """Datagrams from the vehicle 1/1 and the expected (frame, code, message) of each unsigned frame."""
    signed, plain = signer(SHA_KEY, 1, 1), signer(None, 1, 1)
    old = v1.MAVLink(None, srcSystem=1, srcComponent=1)
    other = signer(None, 2, 1)
    datagrams = [
        _attitude(plain),  # 1: before 1/1 signs: no note
        heartbeat(signed),  # 2: 1/1 signs from here
        _attitude(plain),  # 3: unsigned MAVLink 2
        bytes(old.heartbeat_encode(2, 3, 0, 0, 4, 3).pack(old)),  # 4: MAVLink 1
        radio_status(plain),  # 5: RADIO_STATUS: no note
        _attitude(other),  # 6: 2/1 does not sign: no note
        heartbeat(signed) + _attitude(plain),  # 7: signed, then unsigned in the same datagram
    ]
    path = write_udp_pcap(tmp / "unsigned.pcap", [(VEHICLE, GCS, d) for d in datagrams])
    what = "from 1/1, which sends signed frames"
    expected = [(1, None, None), (3, "unsigned-in-signed-stream", f"unsigned ATTITUDE {what}"),
                (4, "v1-in-signed-stream", f"MAVLink v1 HEARTBEAT {what}"), (5, None, None), (6, None, None),
                (7, "unsigned-in-signed-stream", f"unsigned ATTITUDE {what}")]
    return path, expected


@pytest.mark.parametrize("keys", [(), ("--key", "hex:" + SHA_KEY.hex())], ids=["no-key", "key"])
def test_unsigned_frames_of_a_signing_sender_get_the_stages_note_on_both_engines(cli: Cli, tmp_path: Path,
                                                                                keys: tuple[str, ...]) -> None:
    path, expected = _capture(tmp_path)
    for form in (("-T", "jsonl"), ()):
        native = cli("read", str(path), *form, *keys, environ={})
        pure = cli("read", str(path), *form, *keys, environ={"MAVSCOPE_PURE": "1"})
        assert native == pure and native.status == 0
    rows = [json.loads(line) for line in cli("read", str(path), "-T", "jsonl", *keys, environ={}).out.splitlines()]
    unsigned = [r for r in rows if r["signature"] is None]
    got = [(r["frame"], r["notes"][0]["code"], r["notes"][0]["message"]) if r["notes"] else (r["frame"], None, None)
           for r in unsigned]
    assert got == expected
    for r in unsigned:
        for n in r["notes"]:  # the offset of the frame's first byte: 42 bytes of headers into its record
            assert n["severity"] == "warn" and isinstance(n["offset"], int)


def test_the_native_walk_hands_none_of_them_back(tmp_path: Path) -> None:
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.native.core import _native
    from mavscope.native.walk import NativeWalk

    if _native is None:
        pytest.skip("the C extension is not built")
    path, _ = _capture(tmp_path)
    with NativeWalk(path, load_dialect(()), set(), set()) as walk:
        list(walk.batches(lambda: True))
        stats = walk.stats()
    assert stats["records_handed_back"] == 0 and stats["frames_native"] == 8
