"""The capture files, written with `struct` rather than scapy's writers: those take time from float
seconds (rounding) or from the wall clock, and cannot give two pcapng interfaces different time
resolutions. Each writer returns the file offset of every record's data, for expected.json."""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

from .constants import BASE_TIME_US, SNAPLEN
from .packets import Pkt


def write_pcap(path: Path, linktype: int, pkts: Sequence[Pkt]) -> list[int]:
    """Classic pcap, microsecond timestamps, little-endian. Returns the file offset of each record's data."""
    out = bytearray(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, SNAPLEN, linktype))
    offsets = []
    for p in pkts:
        t_us = BASE_TIME_US + p.t_ns // 1000
        out += struct.pack("<IIII", t_us // 1_000_000, t_us % 1_000_000, len(p.data), len(p.data))
        offsets.append(len(out))
        out += p.data if p.cut_to is None else p.data[:p.cut_to]
    path.write_bytes(bytes(out))
    return offsets


def _pcapng_block(block_type: int, body: bytes) -> bytes:
    body += b"\0" * (-len(body) % 4)
    return struct.pack("<II", block_type, len(body) + 12) + body + struct.pack("<I", len(body) + 12)


def _pcapng_options(options: Sequence[tuple[int, bytes]]) -> bytes:
    out = b""
    for code, value in options:
        out += struct.pack("<HH", code, len(value)) + value + b"\0" * (-len(value) % 4)
    return out + struct.pack("<HH", 0, 0) if options else out


def write_pcapng(path: Path, interfaces: Sequence[tuple[int, str, int]], pkts: Sequence[Pkt]) -> list[int]:
    """pcapng: one SHB, one IDB per (linktype, name, tsresol), one EPB per packet. Returns data offsets."""
    out = bytearray(_pcapng_block(0x0A0D0D0A, struct.pack("<IHHq", 0x1A2B3C4D, 1, 0, -1) + _pcapng_options(
        [(4, b"mavscope scripts/make_captures.py")])))  # shb_userappl: in the bytes, so kept as is
    for linktype, name, tsresol in interfaces:
        opts = [(2, name.encode())] + ([(9, bytes([tsresol]))] if tsresol != 6 else [])  # if_name, if_tsresol
        out += _pcapng_block(1, struct.pack("<HHI", linktype, 0, SNAPLEN) + _pcapng_options(opts))
    offsets = []
    for p in pkts:
        tsresol = interfaces[p.iface][2]
        ts = (BASE_TIME_US * 1000 + p.t_ns) // 10 ** (9 - tsresol)
        body = struct.pack("<IIIII", p.iface, ts >> 32, ts & 0xFFFF_FFFF, len(p.data), len(p.data)) + p.data
        offsets.append(len(out) + 28)
        out += _pcapng_block(6, body)
    path.write_bytes(bytes(out))
    return offsets


def write_tlog(path: Path, records: Sequence[tuple[int, bytes]]) -> list[int]:
    """QGroundControl tlog: each (capture time in µs, frame) as an 8-byte big-endian UNIX time in µs
    followed by the frame. Returns the file offset of each frame."""
    out, offsets = bytearray(), []
    for t_us, data in records:
        out += struct.pack(">Q", BASE_TIME_US + t_us)
        offsets.append(len(out))
        out += data
    path.write_bytes(bytes(out))
    return offsets
