"""Messages of a tlog or raw capture read by pymavlink alone (no mavscope import): the independent side of
the cross-checks on real captures.

A tlog is read record by record: 8 bytes of big-endian microseconds, then one frame whose length its
header gives; pymavlink's `MAVLink.decode()` checks the CRC (with CRC_EXTRA) and unpacks it. Bytes that
do not start such a record (ArduPilot autotest tlogs hold SITL console text as one-byte records) are
skipped one at a time (pymavlink's own tlog reader, mavutil, is not record-based and loses real frames
next to such text). A raw stream goes through pymavlink's
streaming parser with robust parsing.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any, NamedTuple

from pymavlink.dialects.v20 import all as mavlink


class Msg(NamedTuple):
    index: int  # position among the capture's frames
    time: float | None  # tlog timestamp (Unix seconds); None in a raw stream
    src: tuple[int, int]
    name: str
    msg: Any  # the pymavlink message


DAY_US = 86_400 * 10**6


def header(m: Any) -> tuple[tuple[int, int], int]:
    """((sysid, compid), seq) of a message, from its frame's bytes: pymavlink gives a message it has no
    definition for (UNKNOWN_n) sender 0/0."""
    raw = m.get_msgbuf()
    h = 4 if raw[0] == 0xFD else 2
    return (raw[h + 1], raw[h + 2]), raw[h]


def sender(m: Any) -> tuple[int, int]:
    return header(m)[0]


def read(path: Path) -> list[Msg]:
    data = path.read_bytes()
    if path.suffix == ".tlog":
        return _tlog(data)
    mav = mavlink.MAVLink(None)
    mav.robust_parsing = True
    out: list[Msg] = []
    for m in mav.parse_buffer(data) or []:
        if not isinstance(m, mavlink.MAVLink_bad_data):
            out.append(Msg(len(out), None, sender(m), m.get_type(), m))
    return out


def _tlog(data: bytes) -> list[Msg]:
    mav = mavlink.MAVLink(None)
    out: list[Msg] = []
    last: int | None = None
    o = 0
    while o + 10 <= len(data):
        ts = struct.unpack_from(">Q", data, o)[0]
        stx, length = data[o + 8], data[o + 9]
        size = length + 8 if stx == 0xFE else length + 12 + (13 if o + 10 < len(data) and data[o + 10] & 1 else 0)
        m = None
        if stx in (0xFD, 0xFE) and (last is None or abs(ts - last) < DAY_US):
            try:
                m = mav.decode(bytearray(data[o + 8 : o + 8 + size]))
            except Exception:  # noqa: BLE001 - pymavlink raises its own error types and struct errors
                m = None
        if m is None or isinstance(m, mavlink.MAVLink_bad_data):
            o += 1
            continue
        out.append(Msg(len(out), ts / 1e6, sender(m), m.get_type(), m))
        last = ts
        o += 8 + size
    return out


def read_pcap(path: Path) -> list[Msg]:
    """The frames of a pcap of UDP datagrams, one datagram at a time through pymavlink's robust parser
    (scapy reads the pcap); `index` is the record number (1-based), `time` the packet time."""
    from scapy.layers.inet import UDP
    from scapy.utils import rdpcap

    out: list[Msg] = []
    for number, pkt in enumerate(rdpcap(str(path)), start=1):
        if UDP not in pkt:
            continue
        mav = mavlink.MAVLink(None)
        mav.robust_parsing = True
        for m in mav.parse_buffer(bytes(pkt[UDP].payload)) or []:
            if not isinstance(m, mavlink.MAVLink_bad_data):
                out.append(Msg(number, float(pkt.time), sender(m), m.get_type(), m))
    return out
