"""IPv4 header, UDP and TCP checksums (RFC 791, 768, 793, RFC 8200 8.1): right, wrong, absent, or a sender's
offload placeholder; and the TCP directions whose captured checksums are real (`Directions`: what becomes
of a segment a receiver drops).

A receiving kernel verifies them and drops a datagram or segment whose checksum is wrong before any
application reads it (Linux: `udp_lib_checksum_complete`, `tcp_checksum_complete`). A capture taken on
the sending host shows what its kernel handed the NIC instead: with checksum offload (every Linux
loopback capture, SITL's included) the field holds the pseudo-header's sum, which the NIC (or nobody, on
loopback) completes; Windows' TCP/IP does the same for NDIS miniports ("Offloading Checksum Tasks").
That placeholder is recognised exactly and not judged.

The ones' complement sum of 16-bit big-endian words is the byte string read as one big-endian integer,
modulo 0xFFFF (2**16 is 1 modulo 0xFFFF), with 0 standing for 0xFFFF: one C call for a whole segment.
"""

from __future__ import annotations

from collections import OrderedDict
from enum import Enum

from mavscope.endpoint import Endpoint
from mavscope.notes import GivenUp, Note, note

PROTO_TCP = 6
PROTO_UDP = 17
_M = 0xFFFF


class Checksum(Enum):
    RIGHT = "right"
    ABSENT = "absent"  # UDP over IPv4 with the field 0: no checksum, which a receiver accepts
    OFFLOAD = "offload"  # what a sender's kernel leaves for its NIC to fill in: not judged
    WRONG = "wrong"  # a receiver that checks drops it (IPv6 UDP with the field 0 too)


def ones_sum(data: bytes, start: int, end: int) -> int:
    """The ones' complement sum of data[start:end] (zero-padded to an even length), modulo 0xFFFF."""
    value = int.from_bytes(data[start:end], "big")
    return (value << 8 if (end - start) & 1 else value) % _M


def pseudo_sum(src: bytes, dst: bytes, proto: int, length: int) -> int:
    """The ones' complement sum of the pseudo-header, modulo 0xFFFF (IPv4's and IPv6's hold the same words
    but for the addresses' length and the zeros)."""
    return (int.from_bytes(src, "big") + int.from_bytes(dst, "big") + proto + length) % _M


def judge(v6: bool, src: bytes, dst: bytes, proto: int, data: bytes, l4: int, end: int) -> tuple[Checksum, int, int]:
    """The checksum of the UDP or TCP segment data[l4:end] (all of it captured): its verdict, the field's
    value and the value that would be right (the field's own when it is right, 0 when absent)."""
    at = l4 + (6 if proto == PROTO_UDP else 16)
    field = data[at] << 8 | data[at + 1]
    udp0 = field == 0 and proto == PROTO_UDP
    if udp0 and not v6:
        return Checksum.ABSENT, 0, 0
    pseudo = pseudo_sum(src, dst, proto, end - l4)
    total = (pseudo + ones_sum(data, l4, end)) % _M
    if total == 0 and not udp0:  # the sum of every word is 0xFFFF: right (IPv6 UDP requires one: udp6_csum_init)
        return Checksum.RIGHT, field, field
    rest = (total - field) % _M  # the sum without the field
    right = _M - rest if rest else (_M if proto == PROTO_UDP else 0)
    if not udp0 and field in (pseudo or _M, pseudo_sum(src, dst, proto, 0) or _M):
        # (Windows' large send offload and OpenBSD's TSO leave the sum without the length)
        return Checksum.OFFLOAD, field, right
    return Checksum.WRONG, field, right


def ipv4_header(data: bytes, off: int, ihl: int) -> tuple[Checksum, int, int]:
    """The checksum of the IPv4 header of `ihl` bytes at `off`: its verdict, the field and the right value.
    Linux computes it in software always; a field of 0 is what a sender that leaves it to its NIC shows
    (macOS on its loopback, judep90's capture; Windows with IP checksum offload): not judged."""
    field = data[off + 10] << 8 | data[off + 11]
    total = ones_sum(data, off, off + ihl)
    if total == 0:  # (0 is right once in 65,535 headers: the IP ID walks the checksum through every value)
        return Checksum.RIGHT, field, field
    if field == 0:
        return Checksum.OFFLOAD, 0, 0
    rest = (total - field) % _M
    return Checksum.WRONG, field, _M - rest if rest else 0


MERGE_FLOOR = 1460  # bytes: a TCP segment a receiver merged (GRO, RSC) is larger than one Ethernet frame holds
FRAME_IP = 1500  # bytes: the IP packet one Ethernet frame holds (a sender's LSO packet, IPv4 length 0, is larger)
DIRECTIONS = 65536  # TCP directions remembered as carrying real checksums, the least recently confirmed young forgotten
ESTABLISHED = 16  # right segments that make a direction established (forgotten only when no young one is left)


class Directions:
    """The TCP directions (source, destination) whose captured checksums are real: one carried a segment
    with a right TCP and IPv4 header checksum. A capture taken there (on the wire, at the receiver) shows
    the checksums the receiver checks, so a segment whose checksum is not right there (wrong, a sender's
    offload placeholder, an IPv4 header checksum of 0) is what the receiver dropped, unless it is larger
    than any one segment: a receiver's own merge (Linux's GRO leaves the placeholder on what it merged).
    On any other direction nothing tells real checksums from a capture edited without fixing them.

    The directions remembered are bounded (DIRECTIONS). A direction is young until ESTABLISHED right segments
    confirmed it, and the bound forgets the least recently confirmed young direction first: a flood of made-up
    directions forgets its own, never a connection that was talking before it (a forgotten direction's
    dropped segments would be read into its stream). Each forgetting is said (`capacity`)."""

    __slots__ = ("_largest", "_young", "_established", "limit", "given_up")

    def __init__(self, limit: int = DIRECTIONS, said: list[Note] | None = None) -> None:
        self._largest: dict[tuple[Endpoint, Endpoint], int] = {}  # -> largest right payload
        self._young: OrderedDict[tuple[Endpoint, Endpoint], int] = OrderedDict()  # -> right segments seen
        self._established: OrderedDict[tuple[Endpoint, Endpoint], None] = OrderedDict()
        self.limit = limit
        self.given_up = GivenUp(f"TCP checksum directions (at most {limit:,} remembered)", "directions", said)

    def right(self, direction: tuple[Endpoint, Endpoint], size: int) -> None:
        """A segment of `size` payload bytes with right checksums on `direction`."""
        self._largest[direction] = max(self._largest.get(direction, 0), size)
        if direction in self._established:
            self._established.move_to_end(direction)
        else:
            n = self._young.pop(direction, 0) + 1
            if n >= ESTABLISHED:
                self._established[direction] = None
            else:
                self._young[direction] = n
        while len(self._largest) > self.limit:
            young = bool(self._young) and next(iter(self._young)) != direction
            gone = next(iter(self._young if young else self._established), direction)
            if gone == direction:
                break
            del (self._young if young else self._established)[gone], self._largest[gone]
            self.given_up.add(f"forgot that {gone[0]} -> {gone[1]} carries real checksums, so its segments with "
                              "wrong ones are read into its stream")

    def forget(self, direction: tuple[Endpoint, Endpoint]) -> None:
        """`direction`'s connection ended (a FIN or RST with right checksums): a new one on its 4-tuple starts
        unknown (on a loopback, the kernel's own RST is right and the next connection all placeholders)."""
        self._largest.pop(direction, None)
        self._young.pop(direction, None)
        self._established.pop(direction, None)

    def fate(self, direction: tuple[Endpoint, Endpoint], size: int, dropped: Note | None, verdict: Checksum,
             field: int, right: int, header_zero: bool, offset: int | None,
             reassembled: bool = False) -> tuple[Note | None, bool]:
        """What becomes of a TCP segment of `size` payload bytes on `direction`: the note on it (None: nothing
        to say) and whether it is left out of its stream. `dropped`: the note on an IP header its receiver drops
        it for (a wrong checksum, a length that lies); `verdict`, `field`, `right`: its TCP checksum, judged
        (Checksum.ABSENT where it is not: not captured whole); `header_zero`: an IPv4 header checksum of 0 (or a
        tunnel's or a fragment's that carried it); `reassembled`: from IP fragments (so no receiver's merge)."""
        checked = direction in self._largest
        if dropped is None and verdict is Checksum.RIGHT and not header_zero:
            self.right(direction, size)
            return None, False
        if dropped is not None:
            code, what, offset = dropped.code, dropped.message, dropped.offset
        elif verdict is Checksum.WRONG:
            code, what = "tcp-bad-checksum", f"TCP checksum 0x{field:04x} is wrong (0x{right:04x} is right)"
        elif not checked:
            return None, False  # a sender's placeholders, or not judged: nothing says the checksums are real
        elif verdict is Checksum.OFFLOAD:
            code, what = "tcp-bad-checksum", (f"TCP checksum 0x{field:04x} is the pseudo-header's sum a sender "
                                              f"leaves for its NIC (0x{right:04x} is right)")
        elif header_zero:
            code, what = "ip-bad-checksum", "IPv4 header checksum 0, which a sender leaves for its NIC"
        else:
            return None, False  # not judged (a segment the capture snapped)
        drop = False
        if not checked:
            fate = ("read into its stream all the same: no right checksum is remembered for that direction, so "
                    "nothing says the capture shows what its receiver checked (a capture edited without fixing "
                    "checksums?)")
        elif dropped is None and not reassembled and size > max(MERGE_FLOOR, self._largest[direction]):
            if verdict is not Checksum.WRONG:
                return None, False  # the receiving host's merge of several segments: GRO leaves the placeholder
            fate = ("read into its stream: larger than any one segment of that direction, it may be the receiving "
                    "host's merge of several")
        else:
            fate, drop = ("not read into its stream: that direction has carried right checksums, so the capture's "
                          "are real"), True
        if dropped is None:
            what += f": a receiver that checks drops this segment ({size} bytes)"
        return note(code, f"{what}; {fate}", offset), drop
