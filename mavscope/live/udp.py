"""`live --udp [HOST:]PORT` and `--forward HOST:PORT`: bind a UDP port, maybe relay, record every datagram.

Each datagram becomes a Record holding a synthesised Ethernet/IPv4/UDP (or IPv6/UDP) packet with the
real addresses and ports (`capture.synth.udp_packet`), link type Ethernet, so the offline pipeline and the pcap
writer serve live capture unchanged. The capture time is the kernel's receive timestamp
(SO_TIMESTAMPNS; `time.time()` at receipt where the kernel gives none), so it is not skewed by how long
the datagram waited for the receiver thread. When bound to a wildcard address the destination address
comes from IP_PKTINFO / IPV6_PKTINFO (the address the datagram was really sent to).

Forward mode relays like mavlink-router's UDP endpoints: datagrams arriving on the listening socket go
out to HOST:PORT from a second socket connected to it; datagrams from HOST:PORT go back to the last
sender seen on the listening side. Relaying happens on the receiver thread, before the decoder sees the
datagram, so a slow decoder never delays the link. Each datagram is recorded once, as received: client
-> listening address, and HOST:PORT -> the relay socket's address.
"""

from __future__ import annotations

import select
import socket
import struct
import time
from collections.abc import Callable
from typing import Any, Protocol

from mavscope.capture.base import LINKTYPE_ETHERNET, Record
from mavscope.capture.synth import packed_address, udp_packet
from mavscope.endpoint import Endpoint
from mavscope.errors import MavscopeError, UsageError
from mavscope.live.drops import proc_udp_drops, socket_inode
from mavscope.live.source import (
    SO_RXQ_OVFL,
    SO_TIMESTAMPNS,
    Chunk,
    LiveSource,
    enable_option,
    set_receive_buffer,
    wait_readable,
)

DEFAULT_RCVBUF = 32 << 20  # asked for; the kernel grants up to net.core.rmem_max without CAP_NET_ADMIN
IP_PKTINFO = getattr(socket, "IP_PKTINFO", 8)
IPV6_RECVPKTINFO = getattr(socket, "IPV6_RECVPKTINFO", 49)
IPV6_PKTINFO = getattr(socket, "IPV6_PKTINFO", 50)
_SOL_SOCKET = socket.SOL_SOCKET
_IPPROTO_IP = socket.IPPROTO_IP
_IPPROTO_IPV6 = socket.IPPROTO_IPV6
_TIMESPEC = struct.Struct("=qq")
_BURST = 1024  # datagrams taken from one socket before looking at the others and at stop()
_FINAL_DRAIN_S = 1.0  # at most this long to empty the kernel's buffer after stop()


def parse_endpoint(text: str, *, what: str, default_host: str | None = "0.0.0.0") -> Endpoint:
    """`PORT`, `HOST:PORT` or `[IPV6]:PORT` (HOST may be a name); UsageError with the option name when bad."""
    t = text.strip()
    if t.startswith("["):
        host, close, rest = t[1:].partition("]")
        if not close or not rest.startswith(":"):
            raise UsageError(f"{what}: expected [IPV6]:PORT, got {text!r}")
        port_s = rest[1:]
    elif t.count(":") == 1:
        host, port_s = t.split(":")
    elif ":" not in t:
        host, port_s = "", t
    else:
        raise UsageError(f"{what}: put an IPv6 address in brackets, as in [::1]:14550 (got {text!r})")
    if not host:
        if default_host is None:
            raise UsageError(f"{what}: expected HOST:PORT, got {text!r}")
        host = default_host
    try:
        port = int(port_s)
        if not 0 <= port <= 0xFFFF:
            raise ValueError
    except ValueError:
        raise UsageError(f"{what}: {port_s!r} is not a UDP port (0-65535)") from None
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except socket.gaierror as e:
        raise UsageError(f"{what}: cannot resolve {host!r}: {e.strerror}") from None
    infos.sort(key=lambda i: i[0] != socket.AF_INET)  # prefer IPv4 for names that have both
    family, _, _, _, sockaddr = infos[0]
    return Endpoint(str(sockaddr[0]), port, family)


class BatchReceiver(Protocol):
    """Takes the datagrams waiting on a socket in one call (mavscope._native.Receiver): (pcap records,
    datagrams, payload bytes, latest SO_RXQ_OVFL value or -1, ECONNREFUSED count)."""

    def receive(self, fd: int, limit: int) -> tuple[bytes, int, int, int, int]: ...


class UdpSource(LiveSource):
    """Binds `listen` (and relays to `forward` when given); every datagram received becomes a Record.

    `receiver`, when given, makes a batch receiver for the bound address (packed) and port
    (mavscope._native.Receiver: recvmmsg(2) without the GIL): without `forward` the receiver thread then
    queues Chunks of many datagrams, already as pcap records, instead of one item per datagram
    (`batched`); records() gives the same Records either way.
    """

    linktype = LINKTYPE_ETHERNET
    description = "udp receiver"

    def __init__(self, listen: Endpoint, forward: Endpoint | None = None, rcvbuf: int = DEFAULT_RCVBUF,
                 receiver: Callable[[bytes, int], BatchReceiver] | None = None, **queue_limits: int) -> None:
        super().__init__(**queue_limits)
        self.listen = listen
        self.forward = forward
        self._make_receiver = receiver if forward is None else None  # relaying is per datagram
        self._batch: BatchReceiver | None = None
        self.rcvbuf_wanted = rcvbuf
        self.rcvbuf = 0  # granted (the kernel's figure)
        self.sock: socket.socket | None = None
        self.up: socket.socket | None = None  # forward mode: connected to `forward`
        self.local: tuple[str, int] = ("", 0)
        self.up_local: tuple[str, int] = ("", 0)
        self.last_client: Any = None  # forward mode: where replies go
        self.forwarded = 0  # datagrams relayed (both directions)
        self.forward_errors = 0  # relay sends that failed, replies with no client yet, ICMP errors
        self._ovfl: dict[int, int] = {}  # fd -> latest SO_RXQ_OVFL value
        self._inodes: dict[int, int] = {}

    @property
    def batched(self) -> bool:
        """The receiver queues Chunks (see the class)."""
        return self._make_receiver is not None

    @property
    def bound(self) -> Endpoint:
        """The address actually bound (the port is known here when 0 was asked for)."""
        return Endpoint(self.local[0], self.local[1], self.listen.family)

    def open(self) -> None:
        lst = self.listen
        sock = socket.socket(lst.family, socket.SOCK_DGRAM)
        try:
            if lst.family == socket.AF_INET6 and lst.host == "::":
                sock.setsockopt(_IPPROTO_IPV6, socket.IPV6_V6ONLY, 0)  # [::]:PORT takes IPv4 too
            sock.bind((lst.host, lst.port))
        except OSError as e:
            sock.close()
            raise MavscopeError(f"live: cannot listen on udp {lst}: {e.strerror or e}") from None
        self.sock = sock
        self.local = sock.getsockname()[:2]
        if self._make_receiver is not None:
            self._batch = self._make_receiver(packed_address(self.local[0]), self.local[1])
        self.rcvbuf = set_receive_buffer(sock, self.rcvbuf_wanted)
        self._setup(sock)
        if self.local[0] in ("0.0.0.0", "::"):
            if lst.family == socket.AF_INET:
                enable_option(sock, _IPPROTO_IP, IP_PKTINFO)
            else:
                enable_option(sock, _IPPROTO_IPV6, IPV6_RECVPKTINFO)
        if self.forward is not None:
            fwd = self.forward
            up = socket.socket(fwd.family, socket.SOCK_DGRAM)
            try:
                up.connect((fwd.host, fwd.port))
            except OSError as e:
                up.close()
                raise MavscopeError(f"live: cannot forward to udp {fwd}: {e.strerror or e}") from None
            self.up = up
            self.up_local = up.getsockname()[:2]
            set_receive_buffer(up, self.rcvbuf_wanted)
            self._setup(up)

    def _setup(self, sock: socket.socket) -> None:
        sock.setblocking(False)
        enable_option(sock, _SOL_SOCKET, SO_TIMESTAMPNS)
        if enable_option(sock, _SOL_SOCKET, SO_RXQ_OVFL):
            self._ovfl[sock.fileno()] = 0
        try:
            self._inodes[sock.fileno()] = socket_inode(sock)
        except OSError:
            pass

    def _kernel_drops_now(self) -> int | None:
        total: int | None = None
        for fd, inode in self._inodes.items():
            seen = [v for v in (self._ovfl.get(fd), proc_udp_drops(inode)) if v is not None]
            if seen:
                total = (total or 0) + max(seen)
        return total

    def _close_sockets(self) -> None:
        for s in (self.sock, self.up):
            if s is not None:
                s.close()

    # -- receiver thread ----------------------------------------------------------------------------

    def _receive(self) -> None:
        assert self.sock is not None
        poller = select.poll()
        socks = [self.sock] + ([self.up] if self.up is not None else [])
        by_fd = {s.fileno(): s for s in socks}
        for s in socks:
            poller.register(s, select.POLLIN)
        poller.register(self._wake_r, select.POLLIN)
        stopping = self._stopping
        while not stopping.is_set():
            for fd in wait_readable(poller, 1.0):
                ready = by_fd.get(fd)
                if ready is not None:
                    self._take(ready, _BURST)
        if self._drain:
            deadline = time.monotonic() + _FINAL_DRAIN_S
            while any(self._take(s, _BURST) == _BURST for s in socks) and time.monotonic() < deadline:
                pass

    def _take(self, sock: socket.socket, limit: int) -> int:
        """Receive up to `limit` datagrams waiting on `sock`; return how many."""
        if self._batch is not None:
            return self._take_batch(sock, limit)
        recvmsg = sock.recvmsg
        offer = self._offer
        fd = sock.fileno()
        upstream = sock is self.up
        relay = self.sock if upstream else self.up
        if upstream:
            dst_host, dst_port = self.up_local
        else:
            dst_host, dst_port = self.local
        n = 0
        while n < limit:
            try:
                data, anc, _flags, addr = recvmsg(65535, 256)
            except BlockingIOError:
                break
            except ConnectionRefusedError:  # ICMP port unreachable for an earlier relay to `forward`
                self.forward_errors += 1
                continue
            n += 1
            t = None
            dh = dst_host
            for level, typ, cd in anc:
                if level == _SOL_SOCKET:
                    if typ == SO_TIMESTAMPNS:
                        sec, nsec = _TIMESPEC.unpack_from(cd)
                        t = sec + nsec / 1_000_000_000  # as the pcap reader computes a nanosecond record's time
                    elif typ == SO_RXQ_OVFL:
                        self._ovfl[fd] = int.from_bytes(cd[:4], "little")
                elif level == _IPPROTO_IP and typ == IP_PKTINFO:
                    dh = socket.inet_ntoa(cd[8:12])
                elif level == _IPPROTO_IPV6 and typ == IPV6_PKTINFO:
                    dh = socket.inet_ntop(socket.AF_INET6, cd[:16])
            if t is None:
                t = time.time()
            if relay is not None:
                self._relay(relay, upstream, data, addr)
            size = len(data)
            offer((t, data, addr[0], addr[1], dh, dst_port, size), size)
        return n

    def _take_batch(self, sock: socket.socket, limit: int) -> int:
        """`_take` with the batch receiver: one Chunk of up to `limit` datagrams."""
        assert self._batch is not None
        fd = sock.fileno()
        records, count, size, ovfl, refused = self._batch.receive(fd, limit)
        self.forward_errors += refused
        if ovfl >= 0 and fd in self._ovfl:
            self._ovfl[fd] = ovfl
        if count:
            self._offer_chunk(Chunk(records, count, size))
        return count

    def _relay(self, relay: socket.socket, upstream: bool, data: bytes, addr: Any) -> None:
        try:
            if upstream:
                if self.last_client is None:
                    self.forward_errors += 1  # a reply before any client spoke: nowhere to send it
                    return
                relay.sendto(data, self.last_client)
            else:
                self.last_client = addr
                relay.send(data)
            self.forwarded += 1
        except OSError:
            self.forward_errors += 1

    # -- consumer side ------------------------------------------------------------------------------

    def _record(self, number: int, offset: int, item: tuple[Any, ...]) -> Record:
        t, data, sh, sp, dh, dp, size = item
        packet = udp_packet(sh, sp, dh, dp, data)
        return Record(number, t, LINKTYPE_ETHERNET, packet, offset, len(packet))
