"""802.11 (link type 105) and radiotap (127) headers: where IP starts in a Wi-Fi data frame.

MAVLink telemetry often rides Wi-Fi (ESP8266/ESP32 bridges, companion computers' access points), and a
capture in monitor mode has the radio's frames. A data frame of an open network carries LLC/SNAP and
then IP (or an A-MSDU: several such packets, each decoded); a protected frame is encrypted (WPA2/3:
CCMP or GCMP), decrypted where the network's passphrase was given and its handshake captured (WPA2:
`wpa.py`, `ccmp.py`); a frame whose FCS failed never reached the receiver's network stack, a retransmission
the receiver discarded as a duplicate was read once, and an access point's relay of a station's packet
carries a packet already shown (`air.py` keeps what a receiver remembers): what is not read is said, never
dissected.
Layouts: IEEE 802.11-2016 section 9.2 (MAC header), RFC 1042 (LLC/SNAP), radiotap.org (the capture
header: version 0, its length, the present bitmaps, the Flags field).
"""

from __future__ import annotations

import struct
import zlib
from typing import NamedTuple, cast

from mavscope.transport.air import Air
from mavscope.transport.ccmp import Plain
from mavscope.transport.wpa import ETHERTYPE_EAPOL

_U16LE = struct.Struct("<H").unpack_from
_U32LE = struct.Struct("<I").unpack_from

TYPE_DATA = 2
ASSOCIATION = frozenset((0, 1, 2, 3, 10, 11, 12))  # management subtypes: (re)association, disassociation, (de)auth
FC_TO_DS, FC_FROM_DS, FC_MORE_FRAG, FC_RETRY, FC_PROTECTED, FC_ORDER = 0x01, 0x02, 0x04, 0x08, 0x40, 0x80
SNAP = b"\xaa\xaa\x03"

RADIOTAP_TSFT, RADIOTAP_FLAGS, RADIOTAP_EXT = 0, 1, 31
RT_FLAG_FCS, RT_FLAG_DATAPAD, RT_FLAG_BAD_FCS = 0x10, 0x20, 0x40
MAX_PRESENT_WORDS = 64  # extended present bitmaps walked at most (radiotap sets no limit; 64 is 2,048 fields)



class Undecoded(NamedTuple):
    """A frame the radio layer does not hand on: its note's code and message."""

    code: str  # one of mavscope.notes' "wifi-" codes (wifi-undecoded, wifi-bad-fcs, wifi-retry, wifi-relay...)
    message: str


class Rebuilt(NamedTuple):
    """A frame decrypted or reassembled from fragments: the frame with its MSDU whole and in clear (`data`, a
    new buffer: its bytes are not the record's), what that MSDU holds, and the other records it came from:
    its key's handshake messages, its earlier fragments (written with it by `read -w`, so that the capture
    written can be read the same way)."""

    data: bytes
    link: Link
    records: tuple[int, ...] = ()
    dropped: tuple[str, ...] = ()  # fragments of other MSDUs the receiver dropped meanwhile (`wifi-fragment`)


class Subframes(NamedTuple):
    """An A-MSDU: several packets in one frame, each (ethertype or 0, offset, end)."""

    packets: tuple[tuple[int, int, int], ...]
    problem: str | None  # a subframe that does not fit, where the walk stopped


# (ethertype or 0 for a frame that holds no IP, offset), a malformed header's message, a frame not decoded,
# or an A-MSDU's packets
Link = tuple[int, int] | str | Undecoded | Subframes | Rebuilt
MAX_SUBFRAMES = 1024  # subframes of one A-MSDU read at most (7,935 bytes of 14-byte subframes: 567)


def strip_80211(data: bytes, off: int = 0, pad: bool = False, fcs: bool = False, air: Air | None = None,
                whole: bool = True) -> Link:
    """Where the network header starts in the 802.11 frame at `off` (`pad`: the header padded to 4 bytes;
    `fcs`: the frame ends with its 4-byte FCS; both as radiotap's Flags say; `air`: the capture's duplicate
    detection, relays and WPA2 keys, which a data frame is checked against, its EAPOL frames read and its
    protected ones decrypted with; `whole`: the record is not snapped)."""
    n = len(data) - (4 if fcs else 0)
    if off + 10 > n:
        return f"802.11 header cut short: {n - off} bytes"
    fc0, fc1 = data[off], data[off + 1]
    if fc0 & 3:
        return f"802.11 protocol version {fc0 & 3}"
    if (fc0 >> 2) & 3 != TYPE_DATA:
        if fc0 & 0x0C == 0 and fc0 >> 4 in ASSOCIATION and air is not None and air.wpa is not None and off + 16 <= n:
            air.wpa.association(data[off + 4:off + 10], data[off + 10:off + 16])
        return (0, off)  # management and control frames carry no IP
    subtype = fc0 >> 4
    if subtype & 4:
        return (0, off)  # Null, QoS Null, CF-Ack/Poll without data: no body
    hlen = 24 + (6 if fc1 & FC_TO_DS and fc1 & FC_FROM_DS else 0)
    qos = subtype & 8
    if qos:
        hlen += 2 + (4 if fc1 & FC_ORDER else 0)  # QoS Control, and HT Control with the Order bit
    if off + hlen > n:
        return f"802.11 header cut short: {n - off} of {hlen} bytes"
    sc = _U16LE(data, off + 22)[0]
    qc = off + hlen - (6 if fc1 & FC_ORDER else 2) if qos else 0  # the QoS Control field
    body = off + ((hlen + 3) & ~3 if pad else hlen)  # (past radiotap's padding, which a retransmission may change)
    a1, a2 = data[off + 4:off + 10], data[off + 10:off + 16]
    tid = data[qc] & 0xF if qos else 16  # (16: frames without QoS, which have their own caches)
    retries, wpa = (air.retries, air.wpa) if air is not None else (None, None)
    if retries is not None:
        same = retries.duplicate(a1 + a2 + bytes((tid,)), sc, bool(fc1 & FC_RETRY), data[body:n])
        if same is not None:
            what = (f"802.11 retransmission (Retry bit) of sequence number {sc >> 4}, fragment {sc & 0xF} from "
                    f"{a2.hex(':')} to {a1.hex(':')}")
            if same:
                return Undecoded("wifi-retry", f"{what}: the receiver discarded it as a duplicate of the frame "
                                 "before")
            return Undecoded("wifi-retry-conflict", f"{what} with another body than the frame it repeats: the "
                             "receiver discarded it as a duplicate and kept the first")
    protected = fc1 & FC_PROTECTED
    origin: tuple[int, ...] = ()  # other records the MSDU comes from: its key's handshake, its fragments
    pn: int | None = None
    ident = b""
    if protected:
        if wpa is None:
            return Undecoded("wifi-undecoded", "802.11 data frame protected (WPA2/WPA3 encryption): not decrypted "
                             "(--wifi-key gives a WPA2 network's passphrase)")
        got = wpa.decrypt(data, off, body, n, qc, whole)
        if not isinstance(got, Plain):
            code, message = got
            return message if code == "malformed-packet" else Undecoded(code, message)
        msdu, origin, pn, ident = got
    else:
        msdu = data[body:n]
    fragment, more = sc & 0xF, bool(fc1 & FC_MORE_FRAG)
    header = data[off:off + hlen]
    pieces: tuple[int, ...] = ()  # the records of the MSDU's other fragments
    dropped: tuple[str, ...] = ()
    if fragment or more:
        if air is None:
            return Undecoded("wifi-undecoded", f"802.11 fragment {fragment}: not reassembled")
        if a1[0] & 1:
            return Undecoded("wifi-fragment", f"802.11 fragment {fragment} of sequence number {sc >> 4}, group-"
                             "addressed: no radio fragments those (802.11-2016 10.5), the receiver drops it")
        if not whole:
            return Undecoded("wifi-fragment", f"802.11 fragment {fragment} of sequence number {sc >> 4}, cut short "
                             "by the capture's snap length: not reassembled")
        reassembly = air.fragments.add(a1 + a2, tid, sc, more, header, msdu, air.record, air.time, pn, ident)
        if reassembly.refused is not None:
            code, message = reassembly.refused
            return Undecoded(code, "; ".join((message, *reassembly.said)))
        if reassembly.done is None:
            if reassembly.said:
                return Undecoded("wifi-fragment", "; ".join(reassembly.said))
            return (0, off)  # held, as an IP fragment is: the fragment that completes its MSDU shows it
        header, msdu, pieces = reassembly.done
        dropped = tuple(reassembly.said)
        origin = tuple(sorted({*origin, *pieces}))
    if protected or fragment or more:  # the frame rebuilt: its MSDU whole and in clear, behind its (first) header
        frame = bytes((header[0], header[1] & ~(FC_PROTECTED | FC_MORE_FRAG))) + header[2:22] + \
            bytes((header[22] & 0xF0,)) + header[23:] + msdu
        link: Link = strip_80211(frame)
        at = (frame, 0)
    else:
        frame, link, at = data, _amsdu(data, body, n) if qos and data[qc] & 0x80 else _snap(data, body, n), (data, off)
    if wpa is not None:
        eapol = cast(tuple[int, int], link)[1] if type(link) is tuple and link[0] == ETHERTYPE_EAPOL else None
        if not protected and eapol is None and wpa.protected(a1, a2):  # (EAPOL goes unprotected till keys are in)
            return Undecoded("wifi-unprotected", f"802.11 data frame from {a2.hex(':')} to {a1.hex(':')} without "
                             "protection where their handshake gave them keys: the receiver drops it (only EAPOL "
                             "passes unprotected)")
        if eapol is not None:  # a handshake message (under the keys of the last, if protected)
            record = air.record if air is not None else 0
            wpa.eapol(a1, a2, frame[eapol:n if frame is data else len(frame)], (*pieces, record))
    relay = _relay(air, *at, link, msdu)
    if relay is not None:
        return relay
    return link if frame is data else Rebuilt(frame, link, origin, dropped)


def _relay(air: Air | None, data: bytes, off: int, link: Link, msdu: bytes) -> Undecoded | None:
    """The note on a frame the access point relays (From DS, Address 3 the source) whose `msdu` a station
    sent it before (To DS, Address 3 the destination); a packet sent to the access point is remembered."""
    if air is None or type(link) is not tuple or not link[0]:
        return None
    ds = data[off + 1] & 3
    a1, a2, a3 = data[off + 4:off + 10], data[off + 10:off + 16], data[off + 16:off + 22]
    if ds == 1:
        air.relays.to_ap(a2, a3, msdu)
    elif ds == 2 and air.relays.relayed(a3, a1, msdu):
        return Undecoded("wifi-relay", f"802.11 frame relayed by the access point {a2.hex(':')} from {a3.hex(':')} "
                         f"to {a1.hex(':')}: its packet was shown when {a3.hex(':')} sent it to the access point")
    return None


def _snap(data: bytes, body: int, end: int) -> tuple[int, int]:
    """The ethertype and offset of the packet after the LLC/SNAP header at `body` (0: not SNAP, no IP)."""
    if data[body:body + 3] != SNAP or body + 8 > end:
        return (0, body)
    return ((data[body + 6] << 8) | data[body + 7], body + 8)


def _amsdu(data: bytes, pos: int, n: int) -> Subframes:
    """The packets of the A-MSDU from `pos` to `n` (IEEE 802.11-2016 9.3.2.2.2: DA, SA, a big-endian length,
    the MSDU, padding to 4 bytes but after the last)."""
    out: list[tuple[int, int, int]] = []
    while pos < n:
        if len(out) == MAX_SUBFRAMES:
            return Subframes(tuple(out), f"802.11 A-MSDU of more than {MAX_SUBFRAMES} subframes")
        if pos + 14 > n:
            return Subframes(tuple(out), f"802.11 A-MSDU subframe header cut short at byte {pos}")
        size = (data[pos + 12] << 8) | data[pos + 13]
        start, end = pos + 14, pos + 14 + size
        if end > n:
            return Subframes(tuple(out), f"802.11 A-MSDU subframe of {size} bytes cut short at byte {n}")
        et, off = _snap(data, start, end)
        out.append((et, off, end))
        pos = end + (-(end - pos) % 4)
    return Subframes(tuple(out), None)


def strip_radiotap(data: bytes, air: Air | None = None, whole: bool = True) -> Link:
    """Where the network header starts in a radiotap-headed 802.11 frame (`air`: as strip_80211's;
    `whole`: the record holds the whole frame, so that its FCS, where radiotap says it is there, is checked)."""
    n = len(data)
    if n < 8:
        return f"radiotap header cut short: {n} bytes"
    if data[0] != 0:
        return f"radiotap version {data[0]}"
    rlen = _U16LE(data, 2)[0]
    if rlen < 8 or rlen > n:
        return f"radiotap length {rlen} does not fit the {n}-byte packet"
    words: list[int] = []
    pos = 4
    while True:
        if pos + 4 > rlen or len(words) == MAX_PRESENT_WORDS:
            return f"radiotap present bitmaps run past the header ({rlen} bytes)"
        word = _U32LE(data, pos)[0]
        words.append(word)
        pos += 4
        if not word >> RADIOTAP_EXT & 1:
            break
    present = words[0]
    if present >> RADIOTAP_FLAGS & 1:
        if present >> RADIOTAP_TSFT & 1:
            pos = (pos + 7) & ~7  # TSFT: 8 bytes, aligned to 8 from the header's start
            pos += 8
        if pos >= rlen:
            return f"radiotap Flags field past the header ({rlen} bytes)"
        flags = data[pos]
        if flags & RT_FLAG_BAD_FCS:
            return Undecoded("wifi-bad-fcs", "802.11 frame that failed its FCS check: the radio that received it "
                             "dropped it, so its bytes are not dissected")
        if flags & RT_FLAG_FCS and whole and n - rlen >= 4:
            # the radio's check, where the driver left it to us (most set the flag above; some hand on every frame)
            right, given = zlib.crc32(memoryview(data)[rlen:n - 4]), _U32LE(data, n - 4)[0]
            if right != given:
                return Undecoded("wifi-bad-fcs", f"802.11 frame whose FCS 0x{given:08x} is wrong (0x{right:08x} is "
                                 "right): damaged in the air, the radio that received it dropped it, so its bytes are "
                                 "not dissected")
        return strip_80211(data, rlen, bool(flags & RT_FLAG_DATAPAD), bool(flags & RT_FLAG_FCS), air, whole)
    return strip_80211(data, rlen, air=air, whole=whole)
