"""Hand-made captures for the native engine's tests: MAVLink frames, link/IP/UDP/TCP headers, and pcap,
pcapng and tlog files around them.

Everything is packed with `struct` here (not with mavscope's writers), so byte orders, timestamp
resolutions, offsets and interfaces can be chosen freely, and frames are checksummed with fastcrc's
CRC-16/MCRF4XX and the dialect's CRC_EXTRA (signatures with hashlib), not with mavscope's framer.
"""

from __future__ import annotations

import hashlib
import struct

from fastcrc import crc16

from mavscope.mavlink.dialect import MessageDef

KEY = bytes(range(32))  # the signing key of the generated signed frames
KEY_SPEC = "hex:" + KEY.hex()
SIGNING_EPOCH = 1_420_070_400


# --- MAVLink frames ---------------------------------------------------------------------------


def crc(data: bytes, extra: int) -> int:
    return crc16.mcrf4xx(bytes([extra]), crc16.mcrf4xx(data))


def frame_v2(md: MessageDef | None, msgid: int, payload: bytes, seq: int, sysid: int, compid: int,
             iflags: int = 0, cflags: int = 0, link_id: int = 0, timestamp: int = 0,
             key: bytes | None = None, crc_extra: int | None = None) -> bytes:
    """A MAVLink 2 frame; signed when iflags & 1 (with `key`, else a made-up signature value)."""
    head = struct.pack("<BBBBBBB", 0xFD, len(payload), iflags, cflags, seq, sysid, compid)
    head += struct.pack("<I", msgid)[:3]
    extra = crc_extra if crc_extra is not None else (md.crc_extra if md is not None else 0)
    body = head + payload
    body += struct.pack("<H", crc(body[1:], extra))
    if iflags & 1:
        block = bytes([link_id]) + timestamp.to_bytes(6, "little")
        if key is not None:
            value = hashlib.sha256(key + body + block).digest()[:6]
        else:
            value = hashlib.sha256(body + block).digest()[:6]
        body += block + value
    return body


def frame_v1(md: MessageDef, payload: bytes, seq: int, sysid: int, compid: int) -> bytes:
    body = struct.pack("<BBBBBB", 0xFE, len(payload), seq, sysid, compid, md.id) + payload
    return body + struct.pack("<H", crc(body[1:], md.crc_extra))


# --- link, IP, UDP -------------------------------------------------------------------------------


def _csum(data: bytes) -> int:
    if len(data) % 2:
        data += b"\0"
    s = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while s >> 16:
        s = (s & 0xFFFF) + (s >> 16)
    return ~s & 0xFFFF


def ipv4(src: bytes, dst: bytes, proto: int, l4: bytes, frag: int = 0) -> bytes:
    hdr = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(l4), 1, frag, 64, proto, 0, src, dst)
    return hdr[:10] + struct.pack("!H", _csum(hdr)) + hdr[12:] + l4


def ipv6(src: bytes, dst: bytes, proto: int, l4: bytes) -> bytes:
    return struct.pack("!IHBB16s16s", 6 << 28, len(l4), proto, 64, src, dst) + l4


def udp(sport: int, dport: int, payload: bytes) -> bytes:
    return struct.pack("!HHHH", sport, dport, 8 + len(payload), 0) + payload


def tcp(sport: int, dport: int, seq: int, payload: bytes, flags: int = 0x18) -> bytes:
    return struct.pack("!HHIIBBHHH", sport, dport, seq, 0, 5 << 4, flags, 65535, 0, 0) + payload


LINKTYPES = {"ethernet": 1, "vlan": 1, "null": 0, "loop": 108, "raw": 101, "sll": 113, "sll2": 276,
             "ipv4": 228, "ipv6": 229}


def link(kind: str, ip: bytes, v6: bool) -> bytes:
    """`ip` behind the link-layer header of `kind` (a key of LINKTYPES)."""
    et = 0x86DD if v6 else 0x0800
    if kind == "ethernet":
        return b"\x02\0\0\0\0\x01\x02\0\0\0\0\x02" + struct.pack("!H", et) + ip
    if kind == "vlan":
        return b"\x02\0\0\0\0\x01\x02\0\0\0\0\x02" + struct.pack("!HHH", 0x8100, 10, et) + ip
    if kind == "null":
        return struct.pack("<I", 30 if v6 else 2) + ip
    if kind == "loop":
        return struct.pack(">I", 24 if v6 else 2) + ip
    if kind == "sll":
        return struct.pack("!HHH8sH", 0, 772, 6, b"\0" * 8, et) + ip
    if kind == "sll2":
        return struct.pack("!HHIHBB8s", et, 0, 1, 772, 0, 6, b"\0" * 8) + ip
    return ip  # raw, ipv4, ipv6


# --- capture files -----------------------------------------------------------------------------


def pcap(records: list[tuple[int, int, bytes]], linktype: int, big: bool = False, ns: bool = False,
         snaplen: int = 65535) -> bytes:
    """A classic pcap of (seconds, fraction, data) records."""
    e = ">" if big else "<"
    out = struct.pack(e + "IHHiIII", 0xA1B23C4D if ns else 0xA1B2C3D4, 2, 4, 0, 0, snaplen, linktype)
    for sec, frac, data in records:
        out += struct.pack(e + "IIII", sec, frac, len(data), len(data)) + data
    return out


def _block(e: str, btype: int, body: bytes) -> bytes:
    body += b"\0" * (-len(body) % 4)
    n = len(body) + 12
    return struct.pack(e + "II", btype, n) + body + struct.pack(e + "I", n)


def pcapng(interfaces: list[tuple[int, int | None, int]], packets: list[tuple[int, int, bytes]],
           big: bool = False, simple: frozenset[int] = frozenset()) -> bytes:
    """A pcapng: interfaces as (linktype, if_tsresol byte or None, if_tsoffset); packets as
    (interface, ticks, data); the packets whose index is in `simple` as Simple Packet Blocks."""
    e = ">" if big else "<"
    out = _block(e, 0x0A0D0D0A, struct.pack(e + "IHHq", 0x1A2B3C4D, 1, 0, -1))
    for linktype, tsresol, tsoffset in interfaces:
        opts = b""
        if tsresol is not None:
            opts += struct.pack(e + "HH", 9, 1) + bytes([tsresol]) + b"\0\0\0"
        if tsoffset:
            opts += struct.pack(e + "HHq", 14, 8, tsoffset)
        if opts:
            opts += struct.pack(e + "HH", 0, 0)
        out += _block(e, 1, struct.pack(e + "HHI", linktype, 0, 0) + opts)
    for i, (iface, ticks, data) in enumerate(packets):
        if i in simple:
            out += _block(e, 3, struct.pack(e + "I", len(data)) + data)
        else:
            out += _block(e, 6, struct.pack(e + "IIIII", iface, ticks >> 32, ticks & 0xFFFFFFFF, len(data),
                                            len(data)) + data)
    return out


def tlog(entries: list[tuple[int, bytes]]) -> bytes:
    """A tlog of (microseconds since the epoch, frame) entries."""
    return b"".join(struct.pack(">Q", us) + f for us, f in entries)
