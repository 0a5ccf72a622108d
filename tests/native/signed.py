"""Signed captures for the signing tests of the native engine, and the verdicts they should get.

Frames are signed by pymavlink (`MAVLink.signing`, explicit timestamps, tests/support/security.py) and
packed into pcap (Ethernet/IPv4/UDP, several frames a datagram) or tlog files with tests/native/build.py.
The expected verdicts come from `expected_verdicts`, a model written from the rules of docs/security.md
("Replay rules") that checks each MAC with pymavlink's own `check_signature`, never from mavscope:

- no key at all (no --key, before any leaked key): `no-key`;
- no key's MAC matches: `invalid`;
- a matching key, and the stream (sysid, compid, link_id) has accepted a timestamp at least as new:
  `replay` (with that key's name); else `valid`, and the stream's last accepted timestamp moves on.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import all as v2

from tests.native import build as nh
from tests.support.security import heartbeat, signer

T0 = 1_773_482_400  # capture start, Unix seconds
TS0 = (T0 - nh.SIGNING_EPOCH) * 100_000  # its signature timestamp
SETUP_SIGNING = 256


@dataclass
class Frame:
    raw: bytes
    record: int = 0  # 1-based record number once packed


@dataclass
class Capture:
    """Records of frames (a record: one datagram or tlog entry), in capture order."""

    records: list[list[bytes]] = field(default_factory=list)

    def frames(self) -> list[Frame]:
        return [Frame(f, i) for i, rec in enumerate(self.records, 1) for f in rec]

    def pcap(self, step: float = 0.01) -> bytes:
        out = []
        for i, rec in enumerate(self.records):
            t = T0 + i * step
            first = rec[0]
            sport = 14580 + first[5] if first[0] == 0xFD else 14000  # a port per sender
            pkt = nh.link("ethernet", nh.ipv4(bytes([10, 0, 0, 2]), bytes([10, 0, 0, 1]), 17,
                                              nh.udp(sport, 14550, b"".join(rec))), False)
            sec = int(t)
            out.append((sec, int(round((t - sec) * 1e6)) % 1_000_000, pkt))
        return nh.pcap(out, nh.LINKTYPES["ethernet"])

    def tlog(self, step: float = 0.01) -> bytes:
        entries = []
        for i, rec in enumerate(self.records):
            for j, f in enumerate(rec):
                entries.append((int((T0 + i * step) * 1e6) + j, f))
        return nh.tlog(entries)


def signed_frame(secret: bytes, sysid: int, compid: int, link_id: int, timestamp: int, kind: int = 0,
                 value: float = 0.0) -> bytes:
    """A frame pymavlink signs with `secret` at `timestamp`: HEARTBEAT, COMMAND_LONG or ATTITUDE."""
    mav = signer(secret, sysid, compid, link_id, timestamp)
    if kind == 0:
        return heartbeat(mav)
    if kind == 1:
        msg = mav.command_long_encode(1, 1, 400, 0, value, 0, 0, 0, 0, 0, 0)
    else:
        msg = mav.attitude_encode(int(timestamp) & 0xFFFFFFFF, value, -value, value / 3, 0.0, 0.5, -0.25)
    return bytes(msg.pack(mav))


def unsigned_frame(sysid: int, compid: int) -> bytes:
    return heartbeat(signer(None, sysid, compid))


def setup_signing_frame(secret: bytes, sysid: int = 255, compid: int = 190) -> bytes:
    """An unsigned SETUP_SIGNING carrying `secret` in clear."""
    mav = signer(None, sysid, compid)
    return bytes(mav.setup_signing_encode(1, 1, secret, TS0).pack(mav))


def forged(frame: bytes) -> bytes:
    """The frame with the last byte of its signature changed (the CRC does not cover the signature)."""
    return frame[:-1] + bytes([frame[-1] ^ 0x5A])


def mac_matches(secret: bytes, frame: bytes) -> bool:
    """pymavlink's check_signature on a fresh receiver: a new stream is taken, so it checks the MAC only."""
    mav = v2.MAVLink(None)
    mav.signing.secret_key = secret
    mav.signing.timestamp = 0
    return bool(mav.check_signature(bytearray(frame), frame[5], frame[6]))


def expected_verdicts(frames: Sequence[Frame], keys: Sequence[tuple[str, bytes]],
                      use_leaked: bool) -> list[tuple[str, str | None] | None]:
    """Per frame (status, key name), or None for an unsigned one. Keys have distinct secrets, so at most
    one matches and their order does not matter; with `use_leaked`, SETUP_SIGNING's key (named
    leaked-RECORD) verifies the frames after it."""
    known = list(keys)
    material = bool(keys) or use_leaked
    last: dict[tuple[int, int, int], int] = {}
    out: list[tuple[str, str | None] | None] = []
    for f in frames:
        raw = f.raw
        msgid = int.from_bytes(raw[7:10], "little")
        if not raw[2] & 1:
            out.append(None)
            if use_leaked and msgid == SETUP_SIGNING:
                # payload in wire order: initial_timestamp (8), target_system, target_component, secret_key
                # (32), its trailing zeros trimmed
                secret = raw[10: 10 + raw[1]].ljust(42, b"\0")[10:42]
                if any(secret) and all(secret != k for _, k in known):
                    known.append((f"leaked-{f.record}", secret))
            continue
        if not material or not known:
            out.append(("no-key", None))
            continue
        name = next((n for n, k in known if mac_matches(k, raw)), None)
        if name is None:
            out.append(("invalid", None))
            continue
        stream = (raw[5], raw[6], raw[-13])
        ts = int.from_bytes(raw[-12:-6], "little")
        if stream in last and ts <= last[stream]:
            out.append(("replay", name))
            continue
        last[stream] = ts
        out.append(("valid", name))
    return out


def pcap_frames(data: bytes) -> list[Frame]:
    """The frames of an Ethernet/IPv4/UDP pcap with whole MAVLink 2 frames in each datagram (the bench
    capture), split by their length bytes: record numbers from 1."""
    pos, record, out = 24, 0, []
    while pos + 16 <= len(data):
        incl = struct.unpack_from("<I", data, pos + 8)[0]
        payload = data[pos + 16 + 42: pos + 16 + incl]
        record += 1
        p = 0
        while p < len(payload):
            size = 12 + payload[p + 1] + (13 if payload[p + 2] & 1 else 0)
            out.append(Frame(payload[p: p + size], record))
            p += size
        pos += 16 + incl
    return out
