"""damaged.pcap: one error case per record (garbage, bad CRCs, a cut frame, an unknown message id and
incompat flag, stray start bytes, a file that ends mid-record), each documented in README.md, so that
a decoder's handling of broken input is pinned down case by case."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pymavlink.dialects.v20.common as mav2
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import Ether

from .constants import (
    GCS_UDP_PORT,
    LINKTYPE_ETHERNET,
    LOOPBACK_V4,
    MAV_AUTOPILOT_PX4,
    SENSORS_PRESENT,
    UNKNOWN_INCOMPAT_FLAG,
    UNKNOWN_MSGID,
    VEHICLE_BOOT_OFFSET_MS,
    VEHICLE_COMPID,
    VEHICLE_SYSID,
    VEHICLE_UDP_PORT,
    ZERO_MAC,
)
from .frames import Endpoint, Frame, assert_no_stx, v2_frame
from .packets import Pkt, wrap_packet
from .story import PX4_UDP_STORY, vehicle_state
from .summary import summarize_packets
from .telemetry import vehicle_heartbeat
from .writers import write_pcap


@dataclass(frozen=True)
class DamageCase:
    """One record of damaged.pcap as README.md documents it."""

    record: int
    what: str
    expect: str


@dataclass(frozen=True)
class Junk:
    """Bytes in a datagram that belong to no frame."""

    data: bytes


@dataclass(frozen=True)
class Cut:
    """The first bytes of a frame whose rest is missing."""

    data: bytes


def damaged(outdir: Path) -> tuple[dict[str, Any], list[DamageCase]]:
    """A short UDP capture, one error case per datagram (each documented in README.md)."""
    vehicle = Endpoint(mav2, VEHICLE_SYSID, VEHICLE_COMPID)
    m = vehicle.mav
    state = vehicle_state(PX4_UDP_STORY, 0.0)
    pkts: list[Pkt] = []
    cases: list[DamageCase] = []

    def now() -> int:
        return len(pkts) * 250_000

    def heartbeat() -> Frame:
        return vehicle.pack(vehicle_heartbeat(MAV_AUTOPILOT_PX4)(m, state, now()), now())

    def attitude(roll: float) -> Frame:
        return vehicle.pack(m.attitude_encode(VEHICLE_BOOT_OFFSET_MS + now() // 1000, roll, 0.01, 1.5,
                                              0.002, 0.001, 0.0), now())

    def datagram(parts: Sequence[Frame | Junk | Cut], what: str, expect: str, cut_to: int | None = None) -> None:
        frames, offsets, cuts, junk_at, payload = [], [], [], [], b""
        for part in parts:
            if isinstance(part, Frame):
                frames.append(part)
                offsets.append(len(payload))
            elif isinstance(part, Cut):
                cuts.append(len(payload))
            else:
                junk_at += range(len(payload), len(payload) + len(part.data))
            payload += part.data
        for i in (i for i in junk_at if payload[i] in (0xFD, 0xFE)):
            # a stray start byte must not begin a complete frame: its claimed length runs past the end
            assert i + 2 >= len(payload) or i + payload[i + 1] + (12 if payload[i] == 0xFD else 8) > len(payload)
        udp = (Ether(src=ZERO_MAC, dst=ZERO_MAC)
               / IP(src=LOOPBACK_V4, dst=LOOPBACK_V4, id=31_000 + len(pkts), flags="DF", ttl=64)
               / UDP(sport=VEHICLE_UDP_PORT, dport=GCS_UDP_PORT))
        pkt = wrap_packet(udp, payload, now(), frames, frame_offsets=offsets,
                    cuts=cuts,
                    skipped=sum(len(p.data) for p in parts if isinstance(p, Junk)))
        pkt.cut_to = cut_to
        pkts.append(pkt)
        cases.append(DamageCase(len(pkts), what, expect))

    datagram([heartbeat()], "a clean HEARTBEAT (baseline)", "1 frame, CRC ok")

    junk = b"\x00\x13\x37junk\x00"
    assert_no_stx(junk, "garbage prefix")
    datagram([Junk(junk), attitude(0.01)], f"{len(junk)} garbage bytes, then an ATTITUDE frame",
             f"skipped-bytes ({len(junk)} bytes), then 1 frame, CRC ok")

    fr = vehicle.pack(m.sys_status_encode(SENSORS_PRESENT, SENSORS_PRESENT, SENSORS_PRESENT, 350, 16_300, 42,
                                          95, 0, 0, 0, 0, 0, 0), now())
    flipped = bytearray(fr.data)
    flipped[10 + 4] ^= 0x01  # a payload byte
    assert_no_stx(bytes(flipped[1:]), "bad-CRC SYS_STATUS")
    datagram([Frame(bytes(flipped), fr.sysid, fr.compid, fr.seq, fr.msgid, 2, crc="bad")],
             "SYS_STATUS with one bit of payload byte 4 flipped", "1 frame, bad-crc")

    hb, att = heartbeat(), attitude(0.02)
    cut = att.data[:21]
    assert_no_stx(cut[1:], "truncated ATTITUDE")
    datagram([hb, Cut(cut)], f"HEARTBEAT, then an ATTITUDE frame cut after {len(cut)} of its {len(att.data)} bytes",
             "1 frame, CRC ok; then truncated-frame (not counted as a frame)")

    gpi = vehicle.pack(m.global_position_int_encode(VEHICLE_BOOT_OFFSET_MS + now() // 1000, state.lat, state.lon,
                                                    488_000, 0, 0, 0, 0, 9_000), now())
    att = attitude(0.03)
    bad = bytearray(att.data)
    bad[-1] ^= 0x5A  # the CRC's high byte
    assert_no_stx(bytes(bad[1:]), "bad-CRC ATTITUDE")
    datagram([gpi, Frame(bytes(bad), att.sysid, att.compid, att.seq, att.msgid, 2, crc="bad")],
             "two frames: GLOBAL_POSITION_INT, then an ATTITUDE whose CRC field is wrong",
             "2 frames: the first CRC ok, the second bad-crc")

    seq = vehicle.next_seq()
    unknown = v2_frame(UNKNOWN_MSGID, bytes(range(1, 11)), seq, VEHICLE_SYSID, VEHICLE_COMPID, 0)
    datagram([Frame(unknown, VEHICLE_SYSID, VEHICLE_COMPID, seq, UNKNOWN_MSGID, 2, crc="unchecked")],
             f"message id {UNKNOWN_MSGID} (in no dialect), 10-byte payload, CRC made with CRC_EXTRA 0",
             "1 frame, CRC unchecked, unknown-msgid")

    hb = heartbeat()
    flagged = v2_frame(hb.msgid, hb.data[10:-2], hb.seq, hb.sysid, hb.compid,
                       mav2.MAVLink_heartbeat_message.crc_extra, incompat=UNKNOWN_INCOMPAT_FLAG)
    datagram([Frame(flagged, hb.sysid, hb.compid, hb.seq, hb.msgid, 2)],
             f"HEARTBEAT with incompat flag 0x{UNKNOWN_INCOMPAT_FLAG:02x} set (CRC valid over the flagged header)",
             "1 frame, CRC ok, unknown-incompat-flags (pymavlink and the C library drop it)")

    datagram([Junk(b"\xfe\xfd"), heartbeat(), Junk(b"\xfd\xfe\xfd"), attitude(0.04)],
             "stray bytes fe fd, a HEARTBEAT, stray bytes fd fe fd, an ATTITUDE",
             "2 frames, CRC ok; the 5 stray bytes are skipped-bytes (each would-be frame they start claims a "
             "length that runs past the datagram, and a valid frame starts inside it)")

    hb = heartbeat()
    headers = 14 + 20 + 8
    cut_to = headers + 8
    datagram([Cut(hb.data)],
             f"a HEARTBEAT in the last record; the file ends {cut_to} bytes into the record's {headers + len(hb.data)}",
             f"record-truncated; the UDP payload ends after 8 of the frame's {len(hb.data)} bytes: "
             "truncated-frame, no frame", cut_to=cut_to)

    offsets = write_pcap(outdir / "damaged.pcap", LINKTYPE_ETHERNET, pkts)
    return summarize_packets("pcap", [LINKTYPE_ETHERNET], pkts, offsets), cases
