"""A flipped bit in a damaged frame's incompat flags is no evidence of encryption.

Found by a review: `audit` on px4_sitl_udp.pcap with a few bits flipped reported error-severity
`keystream-reuse` (and `encrypted-no-key`) and exited 1, because flipped incompat bits 5-7 made bad-CRC
HEARTBEATs look encrypted, and the capture's HEARTBEAT payloads repeat. The sender computes the CRC over
the ciphertext (DOMAIN.md, SecureMAV), so an encrypted frame that arrived whole checks: frames with a bad
CRC are left out of the encryption findings. The same frames with their CRC made good again (pymavlink's
x25crc with HEARTBEAT's CRC_EXTRA, 50, and their UDP checksums made right by scapy) are encrypted frames as
far as anyone can tell, and the repeated ciphertext is reported. A flipped bit on the way also breaks the
UDP checksum, which the damaged capture keeps: its three datagrams are `udp-bad-checksum` findings.
"""

from __future__ import annotations

import json
from pathlib import Path

from pymavlink.generator.mavcrc import x25crc

from tests.conftest import CAPTURES, Cli

HEARTBEAT_CRC_EXTRA = 50  # common.xml, as pymavlink's generated module has it (MAVLink_heartbeat_message.crc_extra)


def heartbeats(data: bytes) -> list[int]:
    """Offsets of the MAVLink 2 HEARTBEATs (STX 0xFD, length 9, no flags, msgid 0) in a capture's bytes."""
    out, pos = [], data.find(b"\xfd\x09\x00\x00")
    while pos >= 0:
        if data[pos + 7 : pos + 10] == b"\x00\x00\x00":
            out.append(pos)
        pos = data.find(b"\xfd\x09\x00\x00", pos + 1)
    return out


def flagged(tmp_path: Path, good_crc: bool) -> str:
    """px4_sitl_udp.pcap with incompat bit 6 (encryption method 2) set on three HEARTBEATs of one sender."""
    data = bytearray((CAPTURES / "px4_sitl_udp.pcap").read_bytes())
    offsets = [p for p in heartbeats(bytes(data)) if data[p + 5] == 1][:3]
    assert len(offsets) == 3
    for p in offsets:
        data[p + 2] |= 0x40
        if good_crc:
            crc = x25crc(bytes(data[p + 1 : p + 10 + 9]))
            crc.accumulate(bytes([HEARTBEAT_CRC_EXTRA]))
            data[p + 19 : p + 21] = crc.crc.to_bytes(2, "little")
    path = tmp_path / ("good.pcap" if good_crc else "flipped.pcap")
    path.write_bytes(bytes(data))
    if good_crc:  # the sender's own frames: scapy computes their UDP checksums afresh
        from scapy.layers.inet import UDP
        from scapy.utils import rdpcap, wrpcap

        packets = rdpcap(str(path))
        for pkt in packets:
            if UDP in pkt:
                del pkt[UDP].chksum
        wrpcap(str(path), packets)
    return str(path)


def codes(cli: Cli, path: str) -> tuple[int, set[str]]:
    status, out, _ = cli("audit", path, "--json")
    return status, {f["code"] for f in json.loads(out)["findings"]}


def test_flipped_flags_on_bad_crc_frames_raise_no_encryption_finding(cli: Cli, tmp_path: Path) -> None:
    status, found = codes(cli, flagged(tmp_path, good_crc=False))
    assert found == {"udp-bad-checksum"}
    assert status == 1


def test_the_same_frames_with_a_good_crc_are_reported(cli: Cli, tmp_path: Path) -> None:
    status, found = codes(cli, flagged(tmp_path, good_crc=True))
    assert {"keystream-reuse", "encrypted-no-key"} <= found and "udp-bad-checksum" not in found
    assert status == 1
