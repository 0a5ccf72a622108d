"""`live --sniff IFACE [--bpf EXPR]`: passive capture through scapy's packet socket (root or CAP_NET_RAW).

scapy opens the AF_PACKET socket, compiles and attaches the BPF filter (libpcap) and sets promiscuous
mode; the receiver thread then reads the socket itself (`recvmsg`, no scapy dissection per packet, which
would cost far more than decoding the MAVLink). Records carry the captured link-layer frames as they
were on the wire, with the interface's link type, so `-w` writes the real packets.

Both directions are captured (packets this host sends too), except on a loopback interface where every
packet would otherwise show up twice (once going out, once coming in): there only the incoming copy is
kept, as tcpdump does. VLAN tags the kernel strips on receive are not put back.
"""

from __future__ import annotations

import logging
import select
import socket
import struct
import time
from typing import Any

from mavscope.capture.base import LINKTYPE_ETHERNET, LINKTYPE_RAW, Record
from mavscope.errors import MavscopeError
from mavscope.live.drops import packet_socket_drops
from mavscope.live.source import SO_TIMESTAMPNS, LiveSource, set_receive_buffer, wait_readable

NEED_PRIVILEGE = "live --sniff needs root or CAP_NET_RAW"
PACKET_OUTGOING = 4
ARPHRD_LOOPBACK = 772
_TIMESPEC = struct.Struct("=qq")
_BURST = 1024
_FINAL_DRAIN_S = 1.0
DEFAULT_RCVBUF = 32 << 20


def linktype_of(hatype: int) -> int:
    """The pcap LINKTYPE for a Linux ARPHRD_* hardware type (Ethernet where unknown)."""
    from scapy.data import ARPHRD_TO_DLT

    dlt = ARPHRD_TO_DLT.get(hatype, LINKTYPE_ETHERNET)
    return LINKTYPE_RAW if dlt == 12 else dlt  # DLT_RAW is 12 on Linux, LINKTYPE_RAW 101 in files


class SniffSource(LiveSource):
    """Every packet on `iface` that passes `bpf` becomes a Record."""

    description = "sniffer"

    def __init__(self, iface: str, bpf: str | None = None, rcvbuf: int = DEFAULT_RCVBUF,
                 **queue_limits: int) -> None:
        super().__init__(**queue_limits)
        self.iface = iface
        self.bpf = bpf
        self.rcvbuf_wanted = rcvbuf
        self.rcvbuf = 0
        self._scapy_sock: Any = None
        self.sock: socket.socket | None = None
        self.loopback = False
        self._kernel_drops = 0
        self._kernel_known = False

    def open(self) -> None:
        try:
            import scapy.arch  # noqa: F401 - sets conf.L2listen for this platform
            from scapy.config import conf
            from scapy.error import Scapy_Exception
        except ImportError as e:  # pragma: no cover - scapy is a dependency
            raise MavscopeError(f"live --sniff needs scapy: {e}") from None
        if conf.L2listen is None:
            raise MavscopeError("live --sniff: scapy has no packet capture on this platform")
        quiet = logging.getLogger("scapy.runtime")
        level = quiet.level
        quiet.setLevel(logging.ERROR)  # "Unable to guess type": mavscope reads the link type itself
        try:
            self._scapy_sock = conf.L2listen(iface=self.iface, filter=self.bpf)
        except PermissionError:
            raise MavscopeError(NEED_PRIVILEGE) from None
        except OSError as e:
            if e.errno in (1, 13):  # EPERM, EACCES
                raise MavscopeError(NEED_PRIVILEGE) from None
            raise MavscopeError(f"live --sniff {self.iface}: {e.strerror or e}") from None
        except (Scapy_Exception, ValueError, ImportError) as e:
            if self.bpf and "libpcap" in str(e):
                raise MavscopeError(f"live --sniff {self.iface}: --bpf needs libpcap to compile the filter "
                                    "(Debian: apt-get install libpcap0.8); without --bpf no library is needed"
                                    ) from None
            raise MavscopeError(f"live --sniff {self.iface}: {e}") from None
        finally:
            quiet.setLevel(level)
        sock: socket.socket = self._scapy_sock.ins
        self.sock = sock
        hatype = sock.getsockname()[3]
        self.loopback = hatype == ARPHRD_LOOPBACK
        self.linktype = linktype_of(hatype)
        self.rcvbuf = set_receive_buffer(sock, self.rcvbuf_wanted)
        try:
            sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        except OSError:
            pass
        sock.setblocking(False)
        packet_socket_drops(sock)  # the kernel counts from open(); reading resets: start from zero

    def _kernel_drops_now(self) -> int | None:
        if self.sock is not None and self.sock.fileno() >= 0:
            got = packet_socket_drops(self.sock)
            if got is not None:
                self._kernel_known = True
                self._kernel_drops += got[1]
        return self._kernel_drops if self._kernel_known else None

    def _close_sockets(self) -> None:
        if self._scapy_sock is not None:
            self._scapy_sock.close()

    def _receive(self) -> None:
        assert self.sock is not None
        poller = select.poll()
        poller.register(self.sock, select.POLLIN)
        poller.register(self._wake_r, select.POLLIN)
        stopping = self._stopping
        fd = self.sock.fileno()
        while not stopping.is_set():
            if fd in wait_readable(poller, 1.0):
                self._take(_BURST)
        if self._drain:
            deadline = time.monotonic() + _FINAL_DRAIN_S
            while self._take(_BURST) == _BURST and time.monotonic() < deadline:
                pass

    def _take(self, limit: int) -> int:
        assert self.sock is not None
        recvmsg = self.sock.recvmsg
        offer = self._offer
        skip_outgoing = self.loopback
        n = 0
        while n < limit:
            try:
                data, anc, _flags, addr = recvmsg(262144, 256)
            except BlockingIOError:
                break
            n += 1
            if skip_outgoing and addr[2] == PACKET_OUTGOING:
                continue
            t = None
            for level, typ, cd in anc:
                if level == socket.SOL_SOCKET and typ == SO_TIMESTAMPNS:
                    sec, nsec = _TIMESPEC.unpack_from(cd)
                    t = sec + nsec * 1e-9
            size = len(data)
            offer((time.time() if t is None else t, data, size), size)
        return n

    def _record(self, number: int, offset: int, item: tuple[Any, ...]) -> Record:
        t, data, size = item
        return Record(number, t, self.linktype, data, offset, size)
