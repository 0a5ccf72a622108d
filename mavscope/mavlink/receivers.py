"""UDP receivers that keep their parser's state from one datagram to the next.

MAVLink's C library keeps one parser per link, and the receivers feed it every byte a UDP port gets, one
datagram after another: PX4's mavlink_receiver (recvfrom, then mavlink_parse_char over the bytes, one
status per instance), QGroundControl's UDPLink (MAVLinkProtocol::receiveBytes, one channel per link),
ArduPilot's GCS_MAVLINK (its UDP ports are byte streams to the parser, as its serial ports are), and
pymavlink's mavudp (one buffer across recv calls). So a frame split over two datagrams to the same
destination is read whole, where mavscope's framer, pymavlink's per-datagram decoding and Wireshark see a
frame cut short at the end of one datagram and bytes that are not MAVLink at the start of the next.
Serial-to-UDP bridges that send whatever bytes they have (socat, ser2net) split frames so; an attacker
can too, to hide a command from per-datagram tools.

`across` walks a datagram as such a receiver: it goes on with what the last datagram to the same
receiver left (`Waiting`: the bytes from the frame the receiver is in, where each entry point is),
with the walks of mavscope.mavlink.hidden, which say where the receiver is at the datagram's end. A
datagram whose receivers are idle at its end (every clean datagram) leaves nothing.

Which datagrams reach one receiver is the receiving socket's business, not the destination address's
(`Sockets`, docs/security.md "Receivers, not addresses"). PX4 (Mavlink::init_udp), ArduPilot (SocketAPM::bind,
`udpin:0.0.0.0:14550`) and QGroundControl (UDPLink: QHostAddress::AnyIPv4) bind one socket to the wildcard
address and a port, so the parser behind it reads every datagram to that port the host gets: to its unicast
addresses, to its subnet's broadcast address and to 255.255.255.255 alike (a dual-stack socket bound to [::]
gets IPv4 datagrams too, as IPv4-mapped addresses). The model, per UDP port:
- a host is the addresses that fold into one (`host_of`): an IPv4-mapped IPv6 address is its IPv4 address,
  every loopback address (127/8, ::1, and 0.0.0.0, which Linux delivers locally) is the one local host;
- a broadcast or multicast datagram (255.255.255.255, an address whose last 7 bits are ones: the broadcast
  of a /25 or wider subnet; 224/4, ff00::/8) reaches every host on its port: each host's receiver goes on
  with it, and the hosts whose receivers were idle share one state (`Port.anon`) until a datagram of their
  own; the capture does not say the netmask, so a broadcast is taken to reach every host on the port;
- one state per port (`Port.wild`) goes on with every datagram to the port, whatever its address: the
  receivers of a host the capture cannot tie its addresses together for (a dual-stack socket's IPv4 and
  IPv6 addresses, a host on two networks). A frame only this state reads is shown with that condition.
The bounds (MAX_PER_PORT hosts a port, MAX_STATES in all) give up the newest state (house policy:
mavscope.notes.pop_newest), never what was there before a flood, and say so (`capacity` notes with the
records and bytes given up), so a flood cannot choose what the analyst loses or lose it silently. The
broadcast's state (`Port.anon`) is never given up for the hosts that left it: past MAX_MOVED hosts told
apart the newest but the one just reached is forgotten (said), and a host not told apart is then read from
each state it may be in (the broadcast's, an idle receiver's, `Port.others`): a frame may be shown twice,
none is hidden for it.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache

from mavscope.endpoint import Endpoint
from mavscope.mavlink.hidden import ACROSS, Candidate, Hidden, Receiver, Scanned, Walking, hidden_frames
from mavscope.notes import GivenUp, Note, note, pop_newest

MAX_PER_PORT = 64  # hosts on one port whose receivers are in a frame at once (the newest let go past it)
MAX_STATES = 8192  # receiver states in a frame over all ports (each holds at most a frame's bytes and its places)
LOOPBACK = "loopback"
WILD = "*"  # the key of a port's state that every datagram to it reaches
FRESH = "idle"  # the key of an idle receiver's walk, where a broadcast needs one besides
ANON = "broadcast"  # the key of the state of the hosts a broadcast left in a frame that had no state of their own
OTHER = "other"  # the keys (OTHER0, OTHER1...) of the other states a host forgotten from Port.moved may be in
MAX_MOVED = 4 * MAX_PER_PORT  # hosts a port tells apart from those a broadcast left in a frame (the newest forgotten)
MAX_OTHERS = 4  # states besides ANON's and an idle one that a forgotten host may be in (the first kept)
_BCAST_BITS = 0x7F  # an IPv4 address whose last 7 bits are ones is taken for a subnet's broadcast (/25 or wider)


@dataclass(frozen=True, slots=True)
class Waiting:
    """What a datagram left its receivers in the middle of: the bytes from the earliest frame one of them is
    in (`tail`), where each is in them, the framer's frames and the hidden frames already shown there, and
    where the bytes came from: (position in tail, record, file offset or None, destination), by position."""

    tail: bytes
    walking: Mapping[Receiver, Walking]
    shown: tuple[Scanned, ...]
    claimed: tuple[int, ...]
    segs: tuple[tuple[int, int, int | None, str], ...]

    def locate(self, pos: int) -> tuple[int | None, tuple[int, ...], tuple[str, ...]]:
        """The file offset of tail position `pos`, the records its bytes from there came in and their
        destinations."""
        i = max(j for j, seg in enumerate(self.segs) if seg[0] <= pos)  # segs[0] starts at 0
        start, _, off, _ = self.segs[i]
        rest = self.segs[i:]
        return (None if off is None else off + pos - start, tuple(seg[1] for seg in rest),
                tuple(dict.fromkeys(seg[3] for seg in rest)))

    @property
    def held(self) -> int:
        """Bytes of the frame (or frames) the receivers are in."""
        return len(self.tail)


def across(candidate: Candidate, data: bytes, found: Sequence[Scanned], skipped: Sequence[tuple[int, int]],
           waiting: Waiting | None, record: int, offset: int | None, dst: str = ""
           ) -> tuple[bytes, int, list[Hidden], Waiting | None]:
    """The hidden frames of datagram `data` (record `record` at file offset `offset`, to `dst`, the framer's
    view `found` and `skipped`) for receivers that go on from `waiting`, and what it leaves them in.

    Returns the bytes walked (the waiting tail, then data), where data starts in them, the hidden frames
    by position in them (a frame before that start began in an earlier datagram), and the Waiting for
    the next datagram to the same receiver (None: its receivers are idle at this one's end)."""
    t = 0
    if waiting is None:
        buf = data
        hidden, left = hidden_frames(candidate, data, found, skipped, len(data), len(data))
    else:
        t = len(waiting.tail)
        buf = waiting.tail + data
        found = [(f[0] + t, *f[1:]) for f in found]
        skipped = [(s + t, c) for s, c in skipped]
        hidden, left = hidden_frames(candidate, buf, found, skipped, len(buf), len(buf), True, waiting.walking,
                                     waiting.shown, waiting.claimed)
    if not left:
        return buf, t, hidden, None
    keep = min(w[0] for w in left.values())
    # the frame the receiver is in is the one it parted at: a frame this datagram's end cut short
    walking = {r: (p - keep, at - keep, ACROSS if how is None and at == p else how) for r, (p, at, how) in left.items()}
    segs = [(0, record, offset, dst)] if waiting is None else [*waiting.segs, (t, record, offset, dst)]
    kept: list[tuple[int, int, int | None, str]] = []
    for start, r, o, d in segs:
        if start <= keep:
            kept = [(0, r, None if o is None else o + (keep - start), d)]
        else:
            kept.append((start - keep, r, o, d))
    shown = tuple((f[0] - keep, *f[1:]) for f in (*(waiting.shown if waiting else ()), *found) if f[0] >= keep)
    claimed = tuple(c - keep for c in (*(waiting.claimed if waiting else ()), *(h[0][0] for h in hidden)) if c >= keep)
    return buf, t, hidden, Waiting(buf[keep:], walking, shown, claimed, tuple(kept))


@lru_cache(maxsize=4096)  # a pure function of an interned Endpoint: what it drops is computed again
def host_of(address: str) -> str | None:
    """The receiving host a datagram to `address` reaches, as the addresses that fold into one: None for a
    broadcast or multicast address, which reaches every host on its port."""
    a = ipaddress.ip_address(address)
    if a.version == 6 and a.ipv4_mapped is not None:
        a = a.ipv4_mapped
    if a.is_loopback or a.is_unspecified:
        return LOOPBACK
    if a.is_multicast or (a.version == 4 and int(a) & _BCAST_BITS == _BCAST_BITS):
        return None
    return str(a)


@dataclass(slots=True)
class Port:
    """The receivers on one UDP port that are in a frame: per host (oldest first), the hosts' that a
    broadcast left in one (`anon`, which every host not in `moved` is in), and the wildcard socket's.

    `moved` is bounded (MAX_MOVED, the newest but the one just added forgotten); once a host is forgotten
    (`forgot`), a host not in `moved` may be in `anon`, idle, or in one of `others` (where broadcasts since
    took an idle one), and its datagram is walked from each: a frame may be shown twice, never hidden."""

    hosts: dict[str, Waiting] = field(default_factory=dict)
    anon: Waiting | None = None
    moved: dict[str, None] = field(default_factory=dict)  # hosts that went on from `anon` (or were not in it)
    wild: Waiting | None = None
    forgot: bool = False  # a host was forgotten from `moved`: a host not in it may not be in `anon`
    others: tuple[Waiting, ...] = ()  # (forgot) the states besides `anon` and idle such a host may be in

    def empty(self) -> bool:
        return not self.hosts and self.anon is None and self.wild is None and not self.others


class Sockets:
    """The receiving sockets of a capture's UDP ports (the module's model). `ports` holds only ports with a
    receiver in a frame (the native walker hands every datagram to one of them back: mavscope/native/walk.py)."""

    def __init__(self) -> None:
        self.ports: dict[int, Port] = {}
        self.states = 0
        self.given_up = GivenUp(f"UDP receivers in a frame ({MAX_PER_PORT} hosts a port, {MAX_STATES:,} in all, "
                                f"{MAX_OTHERS} states a forgotten host may be in)", "bytes of frames given up")
        self.forgotten = GivenUp(f"UDP hosts told apart from those a broadcast left in a frame ({MAX_MOVED} a port)",
                                 "hosts")

    def reach(self, dst: Endpoint) -> list[tuple[str, Waiting | None]]:
        """The receiver states a datagram to `dst` goes on with, by key (a host, ANON, WILD, FRESH where an
        idle receiver's walk is needed besides, OTHER+i for `Port.others`), None for an idle one. A unicast
        datagram walks its host's (each it may be in: `Port.forgot`), a broadcast every host's, ANON and the
        others; WILD is always there (the same object where the states are one)."""
        port = self.ports.get(dst.port)
        host = host_of(dst.host)
        if port is None:
            return [(ANON if host is None else host, None), (WILD, None)]
        out: list[tuple[str, Waiting | None]] = []
        others = [(f"{OTHER}{i}", w) for i, w in enumerate(port.others)]
        if host is None:
            out.extend(port.hosts.items())
            out.append((ANON, port.anon))
            out.extend(others)
            if port.anon is not None and (port.forgot or any(h not in port.hosts for h in port.moved)):
                out.append((FRESH, None))
        else:
            own = port.hosts.get(host)
            unknown = own is None and host not in port.moved
            if unknown and port.anon is not None:
                own = port.anon
            out.append((host, own))
            if unknown and port.forgot:  # (a host forgotten from `moved`: idle, or in one of the others)
                out.append((FRESH, None))
                out.extend(others)
        out.append((WILD, port.wild))
        return out

    def settle(self, dst: Endpoint, left: dict[str, Waiting | None]) -> list[Note]:
        """Where the receivers `reach` gave are after the datagram (`left`, by the same keys), and what the
        bounds gave up for it, as notes for its record."""
        port = self.ports.get(dst.port)
        if port is None:
            port = self.ports[dst.port] = Port()
        before = _count(port)
        said = self.given_up.said = self.forgotten.said = []
        host = host_of(dst.host)
        port.wild = left.pop(WILD, None)
        fresh = left.pop(FRESH, None)
        outs: list[Waiting | None] = [left.pop(f"{OTHER}{i}", None) for i in range(len(port.others))]
        if host is None:  # a broadcast: each host's receiver went on with it, the idle ones' from ANON's
            was = port.anon
            port.anon = left.pop(ANON, None)
            if was is None:  # (the ANON walk was an idle receiver's)
                fresh = port.anon
            if was is None and not port.others:  # every host without a state of its own was idle: they are in
                port.moved = dict.fromkeys(port.hosts)  # the new ANON
                port.forgot = False
            else:  # the hosts that had left ANON and were idle are where an idle receiver is now
                idle = [h for h in port.moved if h not in port.hosts]
                port.moved.update(dict.fromkeys(port.hosts))
                if fresh is not None:
                    left.update(dict.fromkeys(idle, fresh))
                if port.forgot:  # a forgotten host that was idle is where an idle receiver is now, too
                    outs.append(fresh)
                    self._keep_others(port, outs, dst.port)
        else:
            if host in left and port.forgot and port.hosts.get(host) is None and host not in port.moved:
                # a forgotten host, walked from each state it may be in: the first kept (ANON's, the others',
                # an idle receiver's: what came first), every other one given up
                ways = {id(w): w for w in (left[host], *outs, fresh) if w is not None}
                kept = next(iter(ways.values()), None)
                left[host] = kept
                for way in ways.values():
                    if way is not kept and way is not port.wild:
                        self._let_go(way, f"one of the states the receiver at {dst.host}:{dst.port} may be in")
            if port.anon is not None or port.forgot:
                port.moved[host] = None
        for h, w in left.items():
            port.hosts.pop(h, None)
            if w is not None:
                port.hosts[h] = w  # the newest last
        while len(port.hosts) > MAX_PER_PORT:
            newest = [h for h in port.hosts if h != host][-1]
            w = port.hosts.pop(newest)
            if w is not port.wild and w is not port.anon:  # (else the frame is still followed there)
                self._let_go(w, f"the receiver at {newest}:{dst.port}")
        if port.anon is None and not port.others:  # every host without a state of its own is idle
            port.moved.clear()
            port.forgot = False
        while len(port.moved) > MAX_MOVED:  # the broadcast's state stays; a host forgotten is taken to be in it
            gone, _ = pop_newest(port.moved, host)
            port.forgot = True
            self.forgotten.add(f"{gone}:{dst.port} is no longer told apart from the hosts a broadcast to the port "
                               "left in a frame: its datagrams are read from each state it may be in (a frame may "
                               "be shown twice, none is hidden)")
        self.states += _count(port) - before
        if port.empty():
            del self.ports[dst.port]
        while self.states > MAX_STATES and len(self.ports) > 1:  # the newest port's go (house policy)
            k, gone_port = pop_newest(self.ports, dst.port)
            self.states -= _count(gone_port)
            for w in {id(w): w for w in (*gone_port.hosts.values(), gone_port.anon, gone_port.wild,
                                         *gone_port.others) if w is not None}.values():
                self._let_go(w, f"a receiver on port {k}")
        return said

    def _keep_others(self, port: Port, outs: list[Waiting | None], number: int) -> None:
        """`Port.others` after a broadcast: where the others and an idle receiver (`outs`) are now, one of each
        state (those that are ANON's or idle drop out), at most MAX_OTHERS (the first kept, the rest given up)."""
        ways = {id(w): w for w in outs if w is not None and w is not port.anon}
        kept = tuple(ways.values())[:MAX_OTHERS]
        for w in tuple(ways.values())[MAX_OTHERS:]:
            if w is not port.wild:
                self._let_go(w, f"one of the states a forgotten host on port {number} may be in")
        port.others = kept

    def _let_go(self, w: Waiting, who: str) -> None:
        _, records, dsts = w.locate(0)
        self.given_up.add(f"{who} was let go in a frame of which {w.held} bytes had come, in record(s) "
                          f"{', '.join(map(str, records))} to {', '.join(dsts)}: a frame it would have read whole "
                          "is not shown", w.held)


def _count(port: Port) -> int:
    """The receiver states a port holds (one object where several receivers are in the same state)."""
    return len({id(w) for w in (*port.hosts.values(), port.anon, port.wild, *port.others) if w is not None})


def split_note(h: Hidden, before: int, records: tuple[int, ...], dsts: tuple[str, ...], offset: int | None,
               wild: bool) -> Note:
    """The note on hidden frame `h`, whose first `before` bytes came in the datagrams of `records` (to
    `dsts`, this datagram's destination last), at file offset `offset`; `wild`: only a socket that every
    one of those destinations reaches reads it (they are not known to be one host's)."""
    (_, size, _, _), _, _, receivers = h
    who = "MAVLink's C library (ArduPilot, PX4, QGroundControl)" if len(receivers) == len(Receiver) else (
        " and ".join(r.value for r in receivers))
    where = ", ".join(dsts)
    cond = (f"if {where} reach one receiving socket (one host's addresses, or a dual-stack socket's IPv4 and "
            f"IPv6 ones), " if wild else "")
    return note("split-frame", f"{cond}{who}, reading the datagrams to its port as one run of bytes (a socket bound "
                f"to the wildcard address gets those to {where}), reads this frame: its first {before} of {size} "
                f"bytes came in record {', '.join(map(str, records))}, the rest in this datagram, where per-datagram "
                "readers (pymavlink's decoding of a capture, Wireshark, mavscope's framer) see a frame cut short "
                "and bytes that are not MAVLink", offset)
