"""Frames with a bad CRC in a datagram: the native walk writes what the framer shows, on both engines.

The framer's rule (mavlink/framing.py, the reference): a frame whose CRC does not match is shown (crc_status
`bad`, note `bad-crc` "CRC 0xNNNN does not match the frame", the CRC as sent) when it ends where the datagram
ends or where a CRC-valid frame begins; two bad frames in a row: the first is skipped bytes. A datagram with
no valid frame is MAVLink only to or from a MAVLink port or a source that sent valid MAVLink before. The
native walk takes such a datagram as it is (no record handed back) when the bad frame is unsigned and does
not end in an STX byte (MAVLink's C parser would start a frame there: hidden.py); anything else is handed
back. Each case below says what the framer shows, worked out by hand from that rule; both engines must
print the same bytes, and the walker must hand back exactly the cases it leaves to Python.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.conftest import Cli
from tests.support.flows import write_udp_pcap
from tests.support.security import SHA_KEY, heartbeat, signer

GCS, VEHICLE, OTHER = ("10.0.0.1", 14550), ("10.0.0.2", 14580), ("10.0.0.9", 40000)


def _attitude(mav: object, roll: float = 0.1) -> bytes:
    return bytes(mav.attitude_encode(1000, roll, 0.2, 0.3, 0.0, 0.0, 0.0).pack(mav))  # type: ignore[attr-defined]


def _bad(frame: bytes, last: int | None = None) -> bytes:
    """The MAVLink 2 frame with its CRC's low byte changed (or its CRC's high byte set to `last`)."""
    b = bytearray(frame)
    at = 10 + b[1]  # the CRC after the header and the payload (a signature, if any, after it)
    if last is None:
        b[at] ^= 0x5A
    else:
        b[at + 1] = last
    return bytes(b)


def _crc(frame: bytes) -> str:
    at = 10 + frame[1]
    return f"{frame[at] | frame[at + 1] << 8:04x}"


def _rows(cli: Cli, path: Path) -> list[dict]:
    return [json.loads(x) for x in cli("read", str(path), "-T", "jsonl", environ={}).out.splitlines()]


def _both(cli: Cli, path: Path, *extra: str) -> None:
    for form in (("-T", "jsonl"), ()):
        native = cli("read", str(path), *form, *extra, environ={})
        pure = cli("read", str(path), *form, *extra, environ={"MAVSCOPE_PURE": "1"})
        assert native == pure and native.status == 0, form


def _handed_back(path: Path) -> int:
    from mavscope.mavlink.dialect import load_dialect
    from mavscope.native.walk import NativeWalk

    with NativeWalk(path, load_dialect(()), set(), set()) as walk:
        list(walk.batches(lambda: True))
        return walk.stats()["records_handed_back"]


@pytest.fixture(autouse=True)
def _built() -> None:
    from mavscope.native.core import available

    if not available({}):
        pytest.skip("the C extension is not built")


def test_bad_frames_the_framer_shows_are_written_natively(cli: Cli, tmp_path: Path) -> None:
    v = signer(None, 1, 1)
    a, b, c, d = (_attitude(v, r) for r in (0.1, 0.2, 0.3, 0.4))
    bad_b, bad_c, bad_d = _bad(b), _bad(c), _bad(d)
    datagrams = [a + bad_b, bad_c + _attitude(v), bad_d]  # bad at the end, bad before a valid one, bad alone
    path = write_udp_pcap(tmp_path / "bad.pcap", [(VEHICLE, GCS, x) for x in datagrams])
    _both(cli, path)
    rows = _rows(cli, path)
    got = [(r["frame"], r["index"], r["crc_status"], [(n["code"], n["message"]) for n in r["notes"]]) for r in rows]
    msg = "CRC 0x{} does not match the frame"
    assert got == [(1, 1, "ok", []), (1, 2, "bad", [("bad-crc", msg.format(_crc(bad_b)))]),
                   (2, 1, "bad", [("bad-crc", msg.format(_crc(bad_c)))]), (2, 2, "ok", []),
                   (3, 1, "bad", [("bad-crc", msg.format(_crc(bad_d)))])]
    # the file offset: pcap header 24, record header 16, Ethernet 14, IPv4 20, UDP 8, then the first frame
    assert rows[1]["notes"][0]["offset"] == 24 + 16 + 42 + len(a)
    assert rows[1]["fields"]["roll"] == pytest.approx(0.2)  # a bad frame's fields are still decoded
    assert _handed_back(path) == 0


def test_what_the_framer_leaves_or_the_c_parser_reads_otherwise_is_python_s(cli: Cli, tmp_path: Path) -> None:
    v = signer(None, 1, 1)
    s = signer(SHA_KEY, 1, 1)
    two_bad = _bad(_attitude(v, 0.1)) + _bad(_attitude(v, 0.2))  # the first: skipped bytes
    ends_in_stx = _bad(_attitude(v, 0.3), last=0xFD)
    signed_bad = _bad(_attitude(s, 0.4))
    path = write_udp_pcap(tmp_path / "other.pcap", [(VEHICLE, GCS, two_bad), (VEHICLE, GCS, ends_in_stx),
                                                    (VEHICLE, GCS, signed_bad)])
    _both(cli, path)
    rows = _rows(cli, path)
    assert [(r["frame"], r["crc_status"]) for r in rows] == [(1, "bad"), (2, "bad"), (3, "bad")]
    assert [n["code"] for n in rows[0]["notes"]] == ["skipped-bytes", "bad-crc"]
    assert _handed_back(path) == 3


def test_no_valid_frame_is_mavlink_only_where_mavlink_is_expected(cli: Cli, tmp_path: Path) -> None:
    v = signer(None, 1, 1)
    lone = _bad(_attitude(v))
    elsewhere, known = ("10.0.0.5", 40001), ("10.0.0.6", 40002)
    path = write_udp_pcap(tmp_path / "trust.pcap", [
        (OTHER, elsewhere, lone),  # no MAVLink port, no known source: not MAVLink, nothing shown
        (known, elsewhere, _attitude(v)),  # a valid frame: `known` is a source of MAVLink from here
        (known, elsewhere, lone),  # shown: its source sent valid MAVLink
        (VEHICLE, GCS, lone),  # shown: MAVLink's ports
    ])
    _both(cli, path)
    assert [(r["frame"], r["crc_status"]) for r in _rows(cli, path)] == [(2, "ok"), (3, "bad"), (4, "bad")]


def test_a_bad_frame_of_a_sender_that_signs_carries_both_notes(cli: Cli, tmp_path: Path) -> None:
    s, v = signer(SHA_KEY, 1, 1), signer(None, 1, 1)
    bad = _bad(_attitude(v))
    path = write_udp_pcap(tmp_path / "both.pcap", [(VEHICLE, GCS, heartbeat(s)), (VEHICLE, GCS, bad)])
    for keys in ((), ("--key", "hex:" + SHA_KEY.hex())):
        _both(cli, path, *keys)
    row = _rows(cli, path)[1]
    assert [n["code"] for n in row["notes"]] == ["bad-crc", "unsigned-in-signed-stream"]  # the framer's first
    assert row["notes"][1]["message"] == "unsigned ATTITUDE from 1/1, which sends signed frames"
    assert _handed_back(path) == 0
